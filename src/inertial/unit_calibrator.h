// In-flight calibration of a redundant unit's scale factors and axis misalignments from the star
// attitudes, in recursive form: what the unit's processor runs (FuseOptions::calibrate_unit) and what
// the ground's batch (`ssiu fuse --calibrate-unit`, unit_inflight.h) is built on.
//
// Per window between two star fixes (non-overlapping: the fix that closes a window does not open the
// next, so that no star error is shared) the gyro rates of the unit propagate the first fix to the
// second; the rotation left, dphi = 2 vec(q_gyro(b)^-1 q_star(b)), is linear in each gyro's error
// e_i = b_i + S_i n_i.w + mu_i u_i.w + nu_i v_i.w (bias, scale factor, two tilts of the axis about the
// normals u = n x e_min, v = n x u): dphi = -sum_k C_{b<-k} P e_k dt (P the rate solver, C the body's
// rotation from sample k to b). The parity V g = V e (4+ gyros) adds what the attitude cannot see.
// Noise: the star errors at both ends and the gyros' white noise (generalised least squares, each
// window's rows whitened). These are the extra filter states of Pittelkau (2001) held in information
// form: the bias is constant within blocks of bias_block_s, and each block's biases are eliminated
// (Schur complement) when the next block begins, so that the memory and the work per sample are fixed
// by the number of gyros. Nothing allocates after construction and nothing throws.
//
// Observability: a scale factor is seen only while the body turns about an axis it senses, a tilt
// while it turns about the axis the tilt leans toward; with the parity, the attitude sees every one of
// the 3N terms only when the body has turned about three independent axes (best/worst combination
// sigmas in UnitCalState; status not_observable until then).
#pragma once

#include <Eigen/Dense>
#include <array>
#include <ostream>

#include "core/json.h"
#include "core/types.h"
#include "inertial/gyro_unit.h"

namespace ssiu {

struct InflightCalOptions {
  double window_s = 10.0;       // star-to-star window (the fix closing one does not open the next)
  double bias_block_s = 600.0;  // the bias is constant within blocks of this length
  // Prior 1-sigma of each scale factor and tilt (the unit's specification; 0 = none, the batch's
  // least squares): the extra states' initial covariance (Pittelkau 2001). With it the estimate is
  // the posterior mean, shrunk toward the unit as it is where the windows say little, so that it
  // can be applied from the start: FuseOptions::calibration sets 300 ppm and 300 arcsec (the top
  // of a unit's errors, docs/fog-calibration.md).
  double prior_scale_factor_sigma_ppm = 0;
  double prior_misalignment_sigma_arcsec = 0;
  void Check() const;  // InputError naming the field
};

// What the calibration has reached (JSON spelling UnitCalStatusName).
enum class UnitCalStatus {
  kOff = 0,        // "off": not asked for (FuseOptions::calibrate_unit false)
  kAccumulating,   // "accumulating": fewer windows than parameters so far
  kNotObservable,  // "not_observable": the body has not yet turned about three independent axes
  kEstimated,      // "estimated": estimates and sigmas (the batch's; the processor applies them)
  kApplied,        // "applied": the processor's gyro outputs are corrected by the estimate
};
const char* UnitCalStatusName(UnitCalStatus s);
inline std::ostream& operator<<(std::ostream& os, UnitCalStatus v) { return os << UnitCalStatusName(v); }

// Fixed-size (no allocation when copied): the processor reports it with the attitude.
struct UnitCalState {
  UnitCalStatus status = UnitCalStatus::kOff;
  int n_gyros = 0;
  int n_windows = 0, n_bias_blocks = 0;  // windows used; bias blocks they fell in
  long windows_dropped = 0;              // windows broken by an unusable sample or too long
  double chi2_per_dof = 0;
  // The sigmas of the best and worst determined combinations of the scale factors and tilts (square
  // roots of the extreme eigenvalues of their covariance, biases marginalised; ppm and arcsec mixed).
  double best_combination_sigma = 0, worst_combination_sigma = 0;
  // Corrections to the unit the estimator was made with (its processor axes and calibration): scale
  // factor (ppm) and the axis' tilts about its two normals (arcsec), with 1-sigma (covariance scaled
  // by max(1, chi2_per_dof); with the prior, the posterior's).
  std::array<double, kMaxGyros> scale_factor_ppm{}, scale_factor_sigma_ppm{};
  std::array<std::array<double, 2>, kMaxGyros> misalignment_arcsec{}, misalignment_sigma_arcsec{};
};

// {"status", "n_windows", "n_bias_blocks", "windows_dropped", "chi2_per_dof", "best_combination_sigma",
// "worst_combination_sigma", "gyros": [{"scale_factor_ppm", "scale_factor_sigma_ppm",
// "misalignment_arcsec": [2], "misalignment_sigma_arcsec": [2]}]} (gyros only once estimated).
Json UnitCalStateToJson(const UnitCalState& s);

// The two normals of a sensing axis (GyroUnit::SensingAxis's convention for the tilts).
void AxisNormals(const Vec3& axis, Vec3* u, Vec3* v);

class InflightCalibrator {
 public:
  static constexpr int kMaxParams = 4 * kMaxGyros;  // 3N calibration terms + the current block's N biases
  using ParMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxParams, kMaxParams>;
  using ParVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxParams, 1>;

  InflightCalibrator() = default;
  // Linearised about `unit`: its processor axes, its noise, the outputs after RemoveCalibratedErrors.
  // InputError for a bad unit (fewer than 4 gyros: no parity, and 3N + N terms from 3 rows a window
  // leave nothing to test) or bad options.
  InflightCalibrator(const GyroUnit& unit, const InflightCalOptions& options);

  // A sample of every gyro: the mean outputs (deg/h, the unit's calibrated errors removed) over
  // (t_prev, t_s], in time order. A non-finite output breaks the open window.
  void AddGyro(double t_s, const GyroVec& g_dph);
  // A sample that cannot be used (an output missing, a gyro out of use, a time jump): the open window
  // is dropped, the next fix opens a new one.
  void BreakWindow();
  // A star fix (body -> inertial, error covariance in body axes, rad^2). Opens a window, or closes the
  // open one when window_s has passed (dropped if more than 1.5 window_s). True when it closed one.
  bool AddFix(double t_s, const Quat& q_inertial_from_body, const Mat3& cov_body_rad2);

  // The estimate from everything so far (a copy of the information is reduced: the state is unchanged).
  // Status accumulating, not_observable or estimated.
  UnitCalState Estimate() const;
  // Gyro i's output error per unit body rate under estimate s, e_i = S n + mu u + nu v (the model of
  // the module comment, dimensionless): the row of E in g = (H + E) w + ...
  Vec3 OutputError(const UnitCalState& s, int i) const;
  int n_gyros() const { return n_; }

 private:
  void Accumulate(const GyroVec& g_rad_s, const Vec3& w_rad_s, double dt_s);
  void CloseWindow(double t_b, const Quat& q_b, const Mat3& cov_b);
  // Eliminates the current block's biases from (info, eta, yy): their information goes into the terms'.
  void EliminateBiases(ParMat* info, ParVec* eta, double* yy) const;

  int n_ = 0, np_ = 0;
  InflightCalOptions opt_;
  GyroAxes h_;
  GyroPinv p_;
  GyroParity v_;
  std::array<Vec3, kMaxGyros> u_{}, w_{};
  GyroVec arw2_;             // angle white noise per gyro, rad^2/s
  Mat3 pwp_ = Mat3::Zero();  // P diag(arw2) P'
  GyroParity vwv_;           // V diag(arw2) V'

  // Accumulated information of the terms and the current block's biases.
  ParMat info_;
  ParVec eta_;
  double yy_ = 0;
  long rows_ = 0;
  int n_windows_ = 0, n_blocks_ = 0, block_windows_ = 0;
  long dropped_ = 0;
  long block_ = 0;
  bool have_t0_ = false;
  double t0_ = 0;

  // The open window.
  bool open_ = false;
  double t_a_ = 0, span_ = 0;
  int n_samples_ = 0;
  Quat q_a_ = Quat::Identity(), q_rel_ = Quat::Identity();
  Mat3 cov_a_ = Mat3::Zero(), q_noise_ = Mat3::Zero();
  Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxParams> a_;  // sum_k R_ak P_i (coefficient) dt
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxGyros, kMaxParams> b_;  // parity regressors
  GyroVec parity_sum_;
  // The last sample (for the hold up to a fix that falls between samples).
  bool have_prev_ = false;
  double t_prev_ = 0;
  GyroVec g_prev_;
  Vec3 w_prev_ = Vec3::Zero();
};

}  // namespace ssiu
