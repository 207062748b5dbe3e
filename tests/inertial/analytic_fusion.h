// A four-FOG unit on a constant body rate with a 1 Hz star tracker, generated in closed form: the
// truth for the inertial tests that must not depend on the simulator (a stage above this one). The
// gyro outputs are the exact mean rate over each interval plus each gyro's bias, white noise of its
// angle random walk and an optional step fault; the star fixes are the true attitude turned by white
// noise of 5 arcsec (cross) and 30 arcsec (roll). Generating allocates nothing. Also the two-head
// processor the unit processor tests use.
#pragma once

#include <cmath>
#include <memory>
#include <random>

#include "core/camera.h"
#include "inertial/gyro_unit.h"
#include "inertial/propagate.h"
#include "inertial/unit_processor.h"
#include "testing/testing.h"

namespace ssiu::testing {

struct AnalyticFusion {
  GyroUnit unit;
  GyroAxes axes;
  Vec3 w_rad_s;
  Quat q0;
  double dt_s;
  GyroVec bias_dph, sigma_dph;
  int fault_gyro = -1;  // 0-based; -1: none
  double fault_t_s = 0, fault_dph = 0;
  double st_cross_rad = 5 * kArcsecToRad, st_roll_rad = 30 * kArcsecToRad;
  std::mt19937_64 rng;
  std::normal_distribution<double> normal{0.0, 1.0};

  // n_gyros: 4 (the default unit, skew gyro along (1,1,1)) or 6 (two more skew axes: with three
  // parity relations a fault is isolated from the parity alone).
  explicit AnalyticFusion(int n_gyros = 4, uint64_t seed = 7) : rng(seed) {
    unit = DefaultFourFogUnit();
    if (n_gyros == 6) {
      unit.axes_body.push_back(Vec3(1, -1, 1).normalized());
      unit.axes_body.push_back(Vec3(-1, 1, 1).normalized());
      unit.gyros.resize(6);
    }
    axes = unit.Axes();
    w_rad_s = Vec3(0.3, -0.5, 0.8).normalized() * (0.1 * kDegToRad);  // 0.1 deg/s slew
    q0 = QuatFromRotationVector(Vec3(0.4, 1.1, -0.7));
    dt_s = 1.0 / unit.rate_hz;
    const double biases[6] = {2.0, -3.0, 1.5, 2.5, -1.0, 0.5};
    bias_dph = GyroVec::Zero(unit.size());
    sigma_dph = GyroVec::Zero(unit.size());
    for (int i = 0; i < unit.size(); ++i) {
      bias_dph[i] = biases[i];
      sigma_dph[i] = unit.gyros[i].arw_deg_per_sqrt_h * 60.0 / std::sqrt(dt_s);  // per sample
    }
  }

  // A step of step_dph on gyro `gyro0` (0-based) from t_s on.
  void SetFault(int gyro0, double t_s, double step_dph) {
    fault_gyro = gyro0;
    fault_t_s = t_s;
    fault_dph = step_dph;
  }

  Quat Truth(double t_s) const { return q0 * QuatFromRotationVector(w_rad_s * t_s); }

  // The outputs of the sample ending at t_s (deg/h).
  GyroVec Gyro(double t_s) {
    GyroVec g = axes * (w_rad_s * kRadSToDph) + bias_dph;
    for (int i = 0; i < g.size(); ++i) g[i] += sigma_dph[i] * normal(rng);
    if (fault_gyro >= 0 && t_s > fault_t_s) g[fault_gyro] += fault_dph;
    return g;
  }

  // A star fix at t_s (body -> inertial) and its covariance (body axes, rad^2).
  Quat Star(double t_s, Mat3* r_body) {
    const Vec3 e(st_cross_rad * normal(rng), st_cross_rad * normal(rng), st_roll_rad * normal(rng));
    *r_body = Vec3(st_cross_rad * st_cross_rad, st_cross_rad * st_cross_rad, st_roll_rad * st_roll_rad).asDiagonal();
    return Truth(t_s) * QuatFromRotationVector(e);
  }

  // Attitude error of an estimate at t_s (rad).
  double ErrorRad(const Quat& q_est, double t_s) const {
    return RotationVectorFromQuat(Truth(t_s).conjugate() * q_est).norm();
  }
};

// The default mission's two 512x512 heads of 16.6 deg, 90 deg apart, on `unit`, with the built-in
// catalog's identifier.
inline std::unique_ptr<UnitProcessor> TwoHeadProcessor(const GyroUnit& unit, const UnitProcessorOptions& options) {
  OpticalHead h1;
  h1.camera = MakeCamera(512, 512, 16.6);
  OpticalHead h2 = h1;
  h2.q_body_from_sensor = Quat(Eigen::AngleAxisd(90 * kDegToRad, Vec3::UnitX()));
  const auto id = std::make_shared<const StarIdentifier>(MakeIdentifierForCamera("", h1.camera, 0.0));
  return std::make_unique<UnitProcessor>(std::vector<OpticalHead>{h1, h2},
                                         std::vector<std::shared_ptr<const StarIdentifier>>{id, id}, unit, options);
}

}  // namespace ssiu::testing
