// Camera self-calibration from solved star frames (`ssiu calibrate`): the frames are solved, then
// fx, fy, the principal point and the lens distortion (k1, k2, p1, p2, each kept only when
// significant) are fitted over all matched stars jointly with every frame's attitude (bundle
// adjustment, Gauss-Newton/Levenberg-Marquardt with Eigen), and solving and fitting alternate.
// Residuals before and after are measured on held-out frames. Head alignment (q_body_sensor of each
// head relative to head 1) from simultaneous solutions of 2-3 heads.
//
//   CameraCalibration c = CalibrateCamera(id, frames, guess, CalibrateOptions{});
//   WriteJsonFile("camera.json", CameraToJson(c.camera));
#pragma once

#include <Eigen/Dense>
#include <map>
#include <ostream>
#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "core/camera.h"

namespace ssiu {

struct CalibrateOptions {
  // Focal length of the guess known to +/- this percent (the frames are solved with this tolerance
  // until the first fit; later rounds use 1 %).
  double fov_tolerance_pct = 5.0;
  int rounds = 3;  // solve-and-fit rounds
  // k1, k2, p1, p2 kept when |value| > this x its sigma; the principal point when it is this many
  // sigmas off the guess's (else held at the guess).
  double significance_sigmas = 3.0;
  double outlier_sigmas = 5.0;  // matches further than this (x the fit's scatter) are left out
  int holdout_every = 4;        // every n-th frame is held out for the before/after residuals; 0 = none
  // A parameter whose sigma exceeds these is reported unobservable and held at the guess (e.g. the
  // principal point of a narrow field, degenerate with the frames' attitudes).
  double max_principal_point_sigma_px = 10.0;
  double max_focal_sigma_pct = 2.0;
  // When fewer than half the frames solve with the guess, the guess with square pixels and with
  // fy = fx/2 and 2 fx is tried too and the one that solves most frames is kept (a wrong aspect
  // solves nothing).
  bool try_aspects = true;
  SolveOptions solve;
  void Check() const;  // throws InputError naming the field
};

struct CalibrationFrame {
  std::string name;
  std::vector<Centroid> centroids;
};

struct CalibratedFrame {
  std::string name;
  SolveStatus status = SolveStatus::kNoMatch;  // the solve's status with the fitted camera
  Quat q_inertial_from_sensor = Quat::Identity();
  Mat3 covariance_rad2 = Mat3::Zero();
  int matches = 0;
  double rms_px = 0;  // fit residual RMS (per axis) of this frame's matches
  bool held_out = false;
};

// "calibrated", or "not_calibrated" (too few frames solved with the guess to fit; camera = guess).
enum class CalibrationStatus { kCalibrated, kNotCalibrated };
inline const char* CalibrationStatusName(CalibrationStatus s) {
  return s == CalibrationStatus::kCalibrated ? "calibrated" : "not_calibrated";
}
inline std::ostream& operator<<(std::ostream& os, CalibrationStatus v) { return os << CalibrationStatusName(v); }

struct CameraCalibration {
  CalibrationStatus status = CalibrationStatus::kNotCalibrated;
  std::string message;
  Camera guess;   // the guess the frames were first solved with (after try_aspects)
  Camera camera;  // fitted; equals guess when not calibrated
  // Fitted parameters, in covariance order: fx_px, fy_px, cx_px, cy_px, k1, k2, p1, p2 (those fitted).
  std::vector<std::string> parameters;
  std::map<std::string, double> value, sigma;
  Eigen::MatrixXd covariance;             // of `parameters`, scaled by the fit's reduced chi-square when > 1
  std::vector<std::string> unobservable;  // "name: why"
  std::vector<std::string> dropped;       // distortion terms (and principal point) left out as not significant
  int frames_solved = 0, stars_used = 0;
  double rms_px = 0;  // all frames, fitted camera (per axis)
  double reduced_chi2 = 0;
  int held_out_frames = 0;
  double held_out_rms_before_px = 0;  // held-out frames, guess camera (attitude fitted per frame)
  double held_out_rms_after_px = 0;   // held-out frames, camera fitted without them
  std::vector<CalibratedFrame> frames;
};

CameraCalibration CalibrateCamera(const StarIdentifier& id, const std::vector<CalibrationFrame>& frames,
                                  const Camera& guess, const CalibrateOptions& options);

Json CameraCalibrationToJson(const CameraCalibration& c);

// Head alignment: attitudes[e][h] is head h's solution at epoch e (status not solved = missing).
// Each head's q_body_sensor relative to head 1 (whose mount is kept): M_h = M_1 R_1^T R_h per epoch,
// averaged with weights (P_h + A P_1 A^T)^-1, A = R_h^T R_1 (P the solutions' covariances).
struct HeadAlignment {
  std::vector<Quat> q_body_sensor;
  std::vector<Mat3> covariance_rad2;  // of the mount's small rotation, in that head's sensor axes
  std::vector<int> epochs_used;
  std::vector<double> chi2_per_dof;  // scatter of the epochs about the mean vs their covariance
};
HeadAlignment AlignHeads(const std::vector<std::vector<AttitudeSolution>>& attitudes, const std::vector<Quat>& mounts);

}  // namespace ssiu
