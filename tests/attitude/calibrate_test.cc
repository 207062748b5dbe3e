// Camera self-calibration (CalibrateCamera) on simulated frames with a known camera, and head
// alignment (AlignHeads) from simultaneous frames of three heads with known mounts.
#include "attitude/calibrate.h"

#include <cmath>
#include <cstdio>
#include <memory>

#include "core/attitude.h"
#include "core/catalog.h"
#include "sim/frame_sim.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

const StarCatalog& Sky() {
  static const StarCatalog sky = LoadXplanetBsc(DefaultBscPath(), 7.0);
  return sky;
}

// Simulated and detected frames of `truth` at random attitudes.
std::vector<CalibrationFrame> Frames(const Camera& truth, const std::vector<Quat>& qs, uint64_t seed0) {
  std::vector<CalibrationFrame> frames;
  FrameSimOptions fo;
  SolveOptions so;
  DetectOptions d = so.detect;
  d.gain_e_per_adu = fo.gain_e_per_adu;
  for (size_t i = 0; i < qs.size(); ++i) {
    const SimulatedFrame sf = SimulateFrame(truth, Sky(), qs[i], fo, seed0 + i);
    frames.push_back(
        {"frame" + std::to_string(i), CentroidsFromDetections(Detect(sf.image.view(), d), so.detector_sigma_scale)});
  }
  return frames;
}

StarIdentifier IdentifierFor(const Camera& cam, double tol_pct) {
  CatalogBuildOptions co;
  co.fov_deg = cam.FovMaxRad() * kRadToDeg * (1 + tol_pct / 100);
  return StarIdentifier(BuildSolverCatalog(Sky(), co));
}

TEST(Calibrate, TwentySimulatedFramesRecoverTheCameraWithinThreeSigma) {
  Camera truth;
  truth.width = 640, truth.height = 480;
  truth.focal_length_px = 2100, truth.focal_length_y_px = 1980;                  // aspect 0.943
  truth.cx_px = 331.0, truth.cy_px = 231.5;                                      // (11.5, -8) px from the centre
  truth.distortion.k1 = -0.6;                                                    // ~2.5 px at the corners
  Camera guess = MakeCamera(640, 480, 2 * std::atan(320.0 / 2140) * kRadToDeg);  // square, 2 % long, centred
  std::vector<Quat> qs;
  for (int i = 0; i < 20; ++i) qs.push_back(RandomAttitude(500 + i));
  const auto frames = Frames(truth, qs, 500);
  CalibrateOptions o;
  o.solve.identify.systematic_px = 0;
  const StarIdentifier id = IdentifierFor(guess, o.fov_tolerance_pct);
  const CameraCalibration c = CalibrateCamera(id, frames, guess, o);
  ASSERT_EQ(c.status, CalibrationStatus::kCalibrated) << c.message;
  const double want[5] = {truth.focal_length_px, truth.FocalYPx(), truth.cx_px, truth.cy_px, truth.distortion.k1};
  const char* names[5] = {"fx_px", "fy_px", "cx_px", "cy_px", "k1"};
  for (int k = 0; k < 5; ++k) {
    const double v = c.value.at(names[k]), s = c.sigma.at(names[k]);
    std::printf("%s %.4f +/- %.4f (truth %.4f, %.2f sigma)\n", names[k], v, s, want[k], (v - want[k]) / s);
    EXPECT_GT(s, 0) << names[k] << " not fitted";
    EXPECT_LT(std::abs(v - want[k]), 3 * s) << names[k];
  }
  std::printf("%s; held out %d: RMS %.3f -> %.3f px\n", c.message.c_str(), c.held_out_frames, c.held_out_rms_before_px,
              c.held_out_rms_after_px);
  EXPECT_LT(c.sigma.at("cx_px"), 5.0);
  EXPECT_GE(c.frames_solved, 19);
  EXPECT_GE(c.held_out_frames, 4);
  EXPECT_LT(c.held_out_rms_after_px, 0.5 * c.held_out_rms_before_px);
  // A principal-point error moves every attitude by about its angle (the degeneracy the joint fit
  // resolves only to sigma_cx / fx): the attitudes are right within that.
  const double tol_arcsec =
      10 + 3 * std::hypot(c.sigma.at("cx_px") / truth.focal_length_px, c.sigma.at("cy_px") / truth.FocalYPx()) *
               kRadToArcsec;
  for (size_t i = 0; i < c.frames.size(); ++i) {
    if (c.frames[i].status == SolveStatus::kSolved) {
      EXPECT_THAT(c.frames[i].q_inertial_from_sensor, QuaternionNear(qs[i], tol_arcsec));
    }
  }
}

TEST(Calibrate, HeadAlignmentFromSimultaneousFramesWithinThreeSigma) {
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  // Nominal mounts (heads.json) and the true ones, off by tens of arcsec.
  const Quat nominal[3] = {Quat::Identity(), Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitX())),
                           Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitY()))};
  auto small = [](double x, double y, double z) {
    const Vec3 v = Vec3(x, y, z) * kArcsecToRad;
    return Quat(Eigen::AngleAxisd(v.norm(), v.normalized()));
  };
  const Quat truth[3] = {nominal[0], nominal[1] * small(40, -25, 60), nominal[2] * small(-30, 50, -45)};
  const int ne = 8;
  std::vector<std::vector<AttitudeSolution>> att(ne, std::vector<AttitudeSolution>(3));
  CalibrateOptions o;
  o.solve.identify.systematic_px = 0;
  const StarIdentifier id = IdentifierFor(cam, 0);
  for (int h = 0; h < 3; ++h) {
    std::vector<Quat> qs;
    for (int e = 0; e < ne; ++e) qs.push_back(RandomAttitude(900 + e) * truth[h]);
    const auto frames = Frames(cam, qs, 900 + 100 * h);
    SolveOptions so = o.solve;
    for (int e = 0; e < ne; ++e) {
      const SolveResult r = SolveCentroids(id, frames[e].centroids, cam, so);
      att[e][h] = r.attitude;
    }
  }
  const std::vector<Quat> mounts(nominal, nominal + 3);
  const HeadAlignment al = AlignHeads(att, mounts);
  for (int h = 1; h < 3; ++h) {
    Quat d = truth[h].conjugate() * al.q_body_sensor[h];
    if (d.w() < 0) d.coeffs() = -d.coeffs();
    const Vec3 err = 2 * d.vec();
    const double nees = err.dot(al.covariance_rad2[h].inverse() * err);
    std::printf("head %d: error %.2f %.2f %.2f arcsec, sigma %.2f %.2f %.2f arcsec, NEES %.2f, %d epochs\n", h,
                err.x() * kRadToArcsec, err.y() * kRadToArcsec, err.z() * kRadToArcsec,
                std::sqrt(al.covariance_rad2[h](0, 0)) * kRadToArcsec,
                std::sqrt(al.covariance_rad2[h](1, 1)) * kRadToArcsec,
                std::sqrt(al.covariance_rad2[h](2, 2)) * kRadToArcsec, nees, al.epochs_used[h]);
    EXPECT_GE(al.epochs_used[h], ne - 1);
    for (int a = 0; a < 3; ++a) {
      const double s = std::sqrt(al.covariance_rad2[h](a, a));
      EXPECT_LT(std::abs(err[a]), 3 * s) << "head " << h << " axis " << a;
      EXPECT_LT(s * kRadToArcsec, 5.0) << "head " << h << " axis " << a;
    }
    // The nominal mount was tens of arcsec off: the estimate is far closer.
    EXPECT_LT(err.norm(), 0.2 * AttitudeErrorRad(nominal[h], truth[h]));
  }
}

}  // namespace
}  // namespace ssiu
