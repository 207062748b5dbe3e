// A redundant unit of single-axis fibre-optic gyros: sensing axes in the body frame, each gyro's
// error model, the sample rate; body rates from the redundant outputs by weighted least squares and
// the parity space that detects a failing gyro (docs/inertial.md).
#pragma once

#include <string>
#include <vector>

#include "core/json.h"
#include "core/types.h"
#include "inertial/fog_error_model.h"

namespace ssiu {

// At most six gyros (conventions: 3..6 axes); fixed-capacity Eigen types keep the per-sample path
// free of heap allocation.
constexpr int kMaxGyros = 6;
using GyroVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxGyros, 1>;
using GyroAxes = Eigen::Matrix<double, Eigen::Dynamic, 3, 0, kMaxGyros, 3>;  // N x 3
using GyroPinv = Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxGyros>;  // 3 x N
using GyroParity = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxGyros, kMaxGyros>;

// Error model of one single-axis FOG. Every term is switched off by a zero value. Output model
// (deg/h), after IEEE Std 952-1997 sec. 8 (rate-gyro model equation):
//   g = (1 + S + A sgn(w) + N |w|) (a' . w(t - delay)) + b + b_flicker(t) + b_rrw(t) + arw noise
//       + thermal(T, dT/dt) + magnetic(B) [+ quantisation of the integrated angle]
struct GyroErrorModel {
  double bias_dph = 0.0;                                           // constant (turn-on) bias
  double arw_deg_per_sqrt_h = 0.01;                                // angle random walk (white rate noise)
  double bias_instability_dph = 0.05;                              // flicker floor, as a sum of Gauss-Markov processes
  std::vector<double> bias_instability_tau_s = {1000.0, 10000.0};  // their correlation times
  double rrw_dph_per_sqrt_h = 0.0;                                 // rate random walk
  double quantization_arcsec = 0.0;                                // angle quantum of the output counter
  double scale_factor_ppm = 0.0;
  double scale_factor_nonlinearity_ppm_per_dps = 0.0;  // extra scale factor per deg/s of |rate|
  double scale_factor_asymmetry_ppm = 0.0;             // + for positive, - for negative rates (IEEE 952 sec. 3)
  double misalignment_arcsec[2] = {0.0, 0.0};          // small tilts of the axis about two normals
  double time_delay_s = 0.0;
  ThermalDriftModel thermal;     // zero-signal drift polynomial (all K = 0: off)
  MagneticSensitivity magnetic;  // deg/h per microtesla (0: off)

  // Standard deviation of each Gauss-Markov component (deg/h), chosen so that the Allan deviation
  // floor of the sum is about bias_instability_dph (a GM process of std s peaks at about 0.62 s,
  // IEEE Std 952 annex C); spreading the same total over the components.
  double GaussMarkovSigmaDph() const;
  // Equivalent rate-random-walk density of the bias drift (deg/h per sqrt(s)) a filter should
  // assume: rrw plus 2 s^2 / tau of each Gauss-Markov component.
  double BiasDriftDphPerSqrtS() const;
  void Check(const std::string& what) const;
};

struct GyroUnit {
  std::vector<Vec3> axes_body;        // unit sensing axes in the body frame
  std::vector<GyroErrorModel> gyros;  // one per axis
  double rate_hz = 100.0;
  // false (default): the error terms describe a unit (a simulated one's truth) that the processor
  // does not know; it uses the axes and the noise only. true (a bench calibration's unit.json,
  // `ssiu fog unit-calibrate`): each gyro's bias_dph and scale factor terms are known and removed
  // from its output (RemoveCalibratedErrors), and its sensing direction is SensingAxis(i).
  bool calibrated = false;

  int size() const { return static_cast<int>(axes_body.size()); }
  GyroAxes Axes() const;  // N x 3, rows are the sensing axes
  // Gyro i's axis tilted by its misalignment_arcsec about the normals u = a x e_min, v = a x u
  // (the direction the simulator uses as the gyro's true sensing axis).
  Vec3 SensingAxis(int i) const;
  GyroAxes SensingAxes() const;  // N x 3
  // The axes the processor solves the rate with: SensingAxes() when calibrated, else Axes().
  GyroAxes ProcessorAxes() const { return calibrated ? SensingAxes() : Axes(); }
  // Inverts g = (1 + S + A sgn(w) + N |w|) w + b for w, per gyro, when calibrated (else leaves g):
  // the processor's view of the calibrated output. Non-finite outputs stay non-finite. Allocates nothing.
  void RemoveCalibratedErrors(GyroVec* g) const;
  // White-noise standard deviation of each gyro as angle random walk (deg/sqrt(h)); where a gyro's
  // ARW is 0 the smallest nonzero one (or 1) stands in, so that weights stay finite.
  GyroVec NoiseArw() const;
  // InputError (naming `file`) for fewer than 3 or more than 6 gyros, a zero axis, an axis set that
  // does not span 3-D, a bad rate or a bad error term.
  void Check(const std::string& file = "unit") const;
};

// Four FOGs: three orthogonal along body x, y, z and one skewed along (1,1,1)/sqrt(3), each with
// navigation-grade noise (ARW 0.01 deg/sqrt(h), bias instability 0.05 deg/h) and no other term.
GyroUnit DefaultFourFogUnit();
// Three orthogonal ideal gyros (used when a log already holds body rates).
GyroUnit OrthogonalTriad(double arw_deg_per_sqrt_h = 0.01, double bias_instability_dph = 0.05);

GyroUnit GyroUnitFromJson(const Json& j, const std::string& file);
Json GyroUnitToJson(const GyroUnit& unit);
GyroUnit LoadGyroUnit(const std::string& path);

// Weighted least-squares body rate from the outputs of the gyros selected by `use` (a 0/1 mask):
//   w = (H' W H)^-1 H' W g   (the minimum-variance estimate for independent noise of weight W).
class RateSolver {
 public:
  RateSolver() = default;
  // Weights 1 / sigma^2. InputError when the selected axes do not span 3-D.
  RateSolver(const GyroAxes& axes, const GyroVec& sigma, const std::vector<bool>& use);
  // The same without an exception (the per-sample path): false, and *out untouched, when the selected
  // axes do not span 3-D. Allocates nothing.
  static bool Make(const GyroAxes& axes, const GyroVec& sigma, const std::vector<bool>& use, RateSolver* out);
  Vec3 Solve(const GyroVec& g) const { return pinv_ * g; }
  const GyroPinv& Pinv() const { return pinv_; }
  // Covariance of the solved rate, (H' W H)^-1, in the unit of sigma squared.
  const Mat3& Cov() const { return cov_; }

 private:
  GyroPinv pinv_;  // 3 x N, zero columns for gyros not used
  Mat3 cov_ = Mat3::Identity();
};

// Orthonormal rows spanning the left null space of the selected rows of H: V H = 0, V V' = I,
// (N_used - 3) x N with zero columns for gyros not used. p = V g is the parity vector; it holds no
// body rate, only gyro errors (Potter & Suman 1977, "Thresholdless redundancy management").
GyroParity ParityMatrix(const GyroAxes& axes, const std::vector<bool>& use);

}  // namespace ssiu
