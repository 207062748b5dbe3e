// The frame simulator's time and motion (time_utc, proper_motion, aberration, velocity_*_kms): the
// truth positions of the stars move by exactly their proper motion and aberration (core/astrometry.h,
// checked against first-order closed forms there); without a time the frame is bit for bit the old one.
#include <cmath>

#include "core/astrometry.h"
#include "core/attitude.h"
#include "core/error.h"
#include "sim/frame_sim.h"
#include "sim_fixtures.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(FrameSimSky, StarsMoveByTheirProperMotionAndTheAberration) {
  const Camera cam = MakeCamera(512, 512, 10.0);
  const Quat q = QuatFromRaDecRoll(1.2, 0.3, 0.4);
  StarCatalog cat = testing::Stars({q * Vec3(0, 0, 1), q * Vec3(0.05, -0.03, 1), q * Vec3(-0.06, 0.04, 1)}, 4.0);
  cat.epoch_year = 2000.0;
  cat.stars[1].pm_ra_rad_per_yr = 1.0 * kArcsecToRad;  // 30 arcsec by 2030
  cat.stars[1].pm_dec_rad_per_yr = -2.0 * kArcsecToRad;
  FrameSimOptions o = testing::Clean();
  const SimulatedFrame still = SimulateFrame(cam, cat, q, o, 3);
  o.time_utc = "2030-01-01T00:00:00Z";
  o.velocity_x_kms = 4, o.velocity_y_kms = -6, o.velocity_z_kms = 1;
  const SimulatedFrame moved = SimulateFrame(cam, cat, q, o, 3);
  ASSERT_EQ(still.stars.size(), 3u);
  ASSERT_EQ(moved.stars.size(), 3u);
  const SkyCorrections sky = SkyForSimulation(o);
  const Vec3 v = EarthBarycentricVelocityMS(sky.time) + Vec3(4e3, -6e3, 1e3);
  const double year = JulianYearTt(sky.time);
  for (size_t k = 0; k < 3; ++k) {
    const CatalogStar& s = cat.stars[k];
    const Vec3 expect = AberrateDirection(PropagateProperMotion(s, 2000.0, year), v);
    const auto p = cam.Project(q.conjugate() * expect);
    ASSERT_TRUE(p);
    EXPECT_NEAR(moved.stars[k].x_px, p->x(), 1e-6);
    EXPECT_NEAR(moved.stars[k].y_px, p->y(), 1e-6);
    // The shift is tens of arcsec: (v/c) sin(theta) up to ~25", plus 67" of proper motion for star 1.
    const double shift_px =
        std::hypot(moved.stars[k].x_px - still.stars[k].x_px, moved.stars[k].y_px - still.stars[k].y_px);
    EXPECT_GT(shift_px * 10.0 * 3600 / 512, k == 1 ? 40.0 : 1.0);
  }
  // Switched off, the stars stay where the catalog puts them.
  o.proper_motion = false;
  o.aberration = false;
  const SimulatedFrame off = SimulateFrame(cam, cat, q, o, 3);
  EXPECT_EQ(off.image.pixels, still.image.pixels);
}

TEST(FrameSimSky, OptionsRoundTripAndBadValuesAreRefused) {
  FrameSimOptions o;
  o.time_utc = "2026-11-24T04:00:00Z";
  o.velocity_x_kms = 7.5;
  o.proper_motion = false;
  const FrameSimOptions back = FrameSimOptionsFromJson(FrameSimOptionsToJson(o), "test");
  EXPECT_EQ(back.time_utc, o.time_utc);
  EXPECT_EQ(back.velocity_x_kms, 7.5);
  EXPECT_FALSE(back.proper_motion);
  EXPECT_TRUE(back.aberration);
  for (const Json& bad : {Json{{"time_utc", "2026-02-30"}}, Json{{"time_utc", 5}}, Json{{"velocity_x_kms", 7.5}},
                          Json{{"time_utc", "2026-01-01"}, {"velocity_y_kms", 300}}, Json{{"aberration", 1}}}) {
    EXPECT_THROW(FrameSimOptionsFromJson(bad, "sim.json"), InputError) << bad.dump();
  }
}

}  // namespace
}  // namespace ssiu
