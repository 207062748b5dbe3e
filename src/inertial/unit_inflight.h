// In-flight calibration of a redundant unit's scale factors and axis misalignments from the star
// attitudes (`ssiu fuse --calibrate-unit`, docs/inertial.md): a batch least-squares estimator over a
// whole log, the equivalent of the extra filter states of Pittelkau (2001) for ground processing.
//
// Per window between two star fixes (non-overlapping windows, so that no star error is shared) the
// gyro rates of the nominal unit propagate the first fix to the second; the rotation left,
// dphi = 2 vec(q_gyro(b)^-1 q_star(b)), is linear in each gyro's error e_i = b_i + S_i n_i.w + mu_i u_i.w
// + nu_i v_i.w (bias, scale factor, two tilts of the axis about the normals u = n x e_min, v = n x u):
// dphi = -sum_k C_{b<-k} P e_k dt (P the rate solver, C the body's rotation from sample k to b). The
// parity V g = V e (4+ gyros) adds what the attitude cannot see. The bias is constant within blocks of
// bias_block_s; noise: the star errors at both ends and the gyros' white noise (GLS).
#pragma once

#include <string>
#include <vector>

#include "core/json.h"
#include "inertial/fuse.h"
#include "inertial/gyro_unit.h"

namespace ssiu {

struct InflightCalOptions {
  double window_s = 10.0;       // star-to-star window (every other one is used)
  double bias_block_s = 600.0;  // the bias is constant within blocks of this length
  void Check() const;           // InputError naming the field
};

struct InflightGyroCal {
  double scale_factor_ppm = 0, scale_factor_sigma_ppm = 0;
  double misalignment_arcsec[2] = {0, 0}, misalignment_sigma_arcsec[2] = {0, 0};
  Vec3 axis = Vec3::UnitX();
};

struct InflightCalResult {
  bool ok = false;
  std::string message;
  std::vector<InflightGyroCal> gyros;
  int n_windows = 0, n_bias_blocks = 0;
  double chi2_per_dof = 0;
  // Observability: the sigmas of the best and worst determined combinations of the scale factors and
  // tilts (square roots of the extreme eigenvalues of their covariance, biases marginalised).
  double best_combination_sigma = 0, worst_combination_sigma = 0;
  GyroUnit unit;  // the nominal unit with the fitted scale factors and axes, calibrated = true
  Json ToJson() const;
};

// `st_sigma_*` when the star log has no sigma columns. Needs a unit log (g1..gN), not body rates.
InflightCalResult CalibrateUnitInFlight(const GyroLog& gyro, const StarTrackerLog& st, const GyroUnit& nominal,
                                        double st_sigma_cross_arcsec, double st_sigma_roll_arcsec,
                                        const InflightCalOptions& options);

}  // namespace ssiu
