// `discover frames` names `aberration` (issue 15): frames whose stars carry an uncorrected observer
// velocity (each star moved towards the apex by (v/c) sin(theta)) and point in several directions;
// the fitted velocity matches the one put in, and neither a clean set nor a focal-length error is
// taken for it.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/astrometry.h"
#include "core/attitude.h"
#include "core/rng.h"
#include "discover/discover_frames.h"
#include "discover_frames_mc.h"
#include "sim/frame_sim.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// Synthetic solved frames: catalog directions as r_inertial, measured pixels from the apparent
// (aberrated by v_m_s) directions seen by `seen` (a focal-length error, say), 0.02 px noise (bright
// stars: the field-scale part of the aberration is at most ~0.03 px at the edge of a 16.6-deg field).
SolvedFrameSet MakeSet(const Camera& cam, const Camera& seen, const Vec3& v_m_s, int frames, bool spread,
                       uint64_t seed) {
  Rng rng(seed);
  SolvedFrameSet set;
  set.width = cam.width, set.height = cam.height;
  for (int f = 0; f < frames; ++f) {
    const Quat q = spread ? RandomAttitude(seed * 100 + f) : QuatFromRaDecRoll(1.0, 0.2 + 0.001 * f, 0.3 * f);
    testing::AddSolvedFrame(&set, q);
    for (int i = 0; i < 40; ++i) {
      FrameStar s;
      s.frame = f;
      s.r_inertial = q * cam.Unproject(Vec2(rng.Uniform(20, cam.width - 21), rng.Uniform(20, cam.height - 21)));
      const auto p = seen.Project(q.conjugate() * AberrateDirection(s.r_inertial, v_m_s));
      if (!p || !cam.InImage(*p, -5)) continue;
      s.mag = rng.Uniform(3, 6);
      s.flux = 1e6 * std::pow(10, -0.4 * s.mag);
      s.x_px = p->x() + 0.02 * rng.Normal(), s.y_px = p->y() + 0.02 * rng.Normal(), s.sigma_px = 0.02;
      set.stars.push_back(s);
    }
  }
  return set;
}

TEST(DiscoverFrames, UncorrectedAberrationIsNamedWithItsVelocity) {
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  const Vec3 v = EarthBarycentricVelocityMS(ParseUtcIso8601("2026-11-24", "t")) + Vec3(2e3, -7e3, 1.5e3);
  const FrameDiscovery d = DiscoverFrames(MakeSet(cam, cam, v, 12, true, 7), cam, {});
  EXPECT_EQ(d.cause, "aberration");
  ASSERT_TRUE(d.parameters.count("velocity_x_kms"));
  const char* axes[3] = {"velocity_x_kms", "velocity_y_kms", "velocity_z_kms"};
  for (int a = 0; a < 3; ++a) {
    const double sigma = d.sigmas.at(axes[a]);
    EXPECT_NEAR(d.parameters.at(axes[a]), v(a) / 1000, 3 * sigma) << axes[a];
    EXPECT_LT(sigma, 8.0);  // 30 km/s found to better than a quarter
  }
  EXPECT_GT(d.gain, 1.0);
  std::printf(
      "aberration: v = (%.1f, %.1f, %.1f) +- (%.1f, %.1f, %.1f) km/s, true (%.1f, %.1f, %.1f); held-out rms %.3f -> "
      "%.3f\n",
      d.parameters.at(axes[0]), d.parameters.at(axes[1]), d.parameters.at(axes[2]), d.sigmas.at(axes[0]),
      d.sigmas.at(axes[1]), d.sigmas.at(axes[2]), v.x() / 1000, v.y() / 1000, v.z() / 1000,
      d.residual_rms_before_arcsec, d.residual_rms_after_arcsec);
}

TEST(DiscoverFrames, AberrationIsNotNamedForCleanFramesOrAFocalLengthError) {
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  EXPECT_EQ(DiscoverFrames(MakeSet(cam, cam, Vec3::Zero(), 12, true, 8), cam, {}).cause, "none");
  Camera longer = cam;
  longer.focal_length_px *= 1.0005;
  EXPECT_EQ(DiscoverFrames(MakeSet(cam, longer, Vec3::Zero(), 12, true, 9), cam, {}).cause, "focal_length");
  // Frames all in one direction cannot tell aberration from a focal length: not tested.
  const FrameDiscovery one = DiscoverFrames(MakeSet(cam, cam, Vec3(3e4, 0, 0), 6, false, 10), cam, {});
  EXPECT_NE(one.cause, "aberration");
  EXPECT_NE(std::find(one.not_tested.begin(), one.not_tested.end(), "aberration"), one.not_tested.end());
}

}  // namespace
}  // namespace ssiu
