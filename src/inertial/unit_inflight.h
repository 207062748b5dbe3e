// In-flight calibration of a redundant unit's scale factors and axis misalignments from the star
// attitudes over a whole log (`ssiu fuse --calibrate-unit`, docs/inertial.md): the recursive estimator
// of unit_calibrator.h (the processor's) fed the log, and solved again about the calibrated unit
// (Gauss-Newton) for what the linearisation leaves.
#pragma once

#include <string>
#include <vector>

#include "core/json.h"
#include "inertial/fuse.h"
#include "inertial/gyro_unit.h"
#include "inertial/unit_calibrator.h"

namespace ssiu {

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
