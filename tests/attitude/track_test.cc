#include <cmath>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/catalog.h"
#include "sim/frame_sim.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// A slewing sequence: 0.5 deg/s about a tilted sensor axis, 10 frames per second. The first frame
// is solved lost in space, the others by tracking; every attitude is near the truth. A jump of
// 5 deg breaks the lock and the tracker falls back to lost in space.
TEST(Tracker, SlewingSequenceThenLostLockRecovery) {
  const StarCatalog sky = LoadXplanetBsc(DefaultBscPath(), 7.0);
  CatalogBuildOptions co;
  co.fov_deg = 16.6;
  const StarIdentifier id(BuildSolverCatalog(sky, co));
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  SolveOptions so;
  Tracker tracker(id, cam, so);
  const Quat q0 = QuatFromRaDecRoll(1.2, 0.4, 0.3);
  const Vec3 w_sensor = Vec3(0.3, 1.0, 0.2).normalized() * 0.5 * kDegToRad;  // rad/s
  FrameSimOptions fo;
  const double dt = 0.1;
  for (int k = 0; k < 12; ++k) {
    const double t = k * dt;
    Quat q = q0 * Quat(Eigen::AngleAxisd(w_sensor.norm() * t, w_sensor.normalized()));
    if (k >= 10) q = q * Quat(Eigen::AngleAxisd(5 * kDegToRad, Vec3::UnitX()));  // sudden jump
    const SimulatedFrame sf = SimulateFrame(cam, sky, q, fo, 50 + k);
    DetectOptions dopt = so.detect;
    dopt.gain_e_per_adu = fo.gain_e_per_adu;
    const SolveResult r =
        tracker.Update(CentroidsFromDetections(Detect(sf.image.view(), dopt), so.detector_sigma_scale), t);
    ASSERT_EQ(r.status, SolveStatus::kSolved) << "frame " << k << ": " << r.message;
    const SolveMode expected_mode = (k == 0 || k == 10) ? SolveMode::kLostInSpace : SolveMode::kTracking;
    EXPECT_EQ(r.mode, expected_mode) << "frame " << k << ": " << r.message;
    EXPECT_LT(SplitAttitudeError(r.attitude.q_inertial_from_sensor, q).cross_rad * kRadToArcsec, 5.0) << "frame " << k;
    EXPECT_THAT(r.attitude.q_inertial_from_sensor, QuaternionNear(q, 60.0)) << "frame " << k;
  }
}

}  // namespace
}  // namespace ssiu
