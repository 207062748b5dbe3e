// Bench calibration of a redundant FOG unit as a whole (`ssiu fog unit-calibrate`): each gyro's bias,
// scale factor (with asymmetry and nonlinearity when significant) and sensing-axis direction from
// multi-position static runs (the Earth's rate) and rate-table runs, logged as
// t_s,g1_dph..gN_dph,ref_x_dph,ref_y_dph,ref_z_dph[,temp_c] (conventions.md: ref is the unit's true
// rate relative to inertial space in its nominal body axes).
//
// Per gyro i the output model (IEEE Std 952-1997 sec. 8, linearised in the small terms) is
//   g = m . w + b + A 1e-6 |n.w| + N 1e-6 (n.w)|n.w|/3600 + kT (T - T_ref) + kG dT/dt + noise,
// with m = (1 + S) a (a = the true unit axis, n = the nominal one), so that the unknowns are linear:
// S = |m| - 1, a = m / |m|. It is fitted by generalised least squares on bin means of the data with
// the noise covariance of white noise (from the data's first differences) plus the Gauss-Markov bias
// wander and rate random walk of the nominal unit's noise model; the optional terms (asymmetry,
// nonlinearity, temperature, temperature rate) are chosen by BIC over all subsets, as `fog thermal`
// chooses eq. (1)'s terms (docs/fog-calibration.md).
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "calibration/fit_status.h"
#include "calibration/fog_thermal.h"
#include "core/json.h"
#include "core/types.h"
#include "inertial/gyro_unit.h"

namespace ssiu {

struct UnitBenchLog {
  std::string file;                        // for messages
  std::vector<double> t_s, temp_c;         // temp_c empty when the log has none
  std::vector<std::vector<double>> g_dph;  // [gyro][sample]
  std::vector<Vec3> ref_dph;
};

// Reads t_s, g1_dph..g{n_gyros}_dph, ref_x_dph, ref_y_dph, ref_z_dph and temp_c when present.
// InputError on a missing column, a non-number, unsorted time or fewer than 10 rows.
UnitBenchLog ReadUnitBenchLog(const std::string& path, int n_gyros);

struct UnitCalibrationOptions {
  double bin_s = 10.0;      // the data are averaged over bins of this length within a step
  double settle_s = 2.0;    // dropped after each step of the reference (table acceleration)
  double step_dph = 100.0;  // a reference change larger than this between samples is a new step
  double temp_ref_c = std::numeric_limits<double>::quiet_NaN();  // the bias's temperature; NaN: the mean logged
  TemperatureRateOptions rate;                                   // T and dT/dt from the temp_c channel
  bool wander_from_unit = true;  // GLS with the nominal unit's bias wander (else white noise only)
  void Check() const;
};

// One term of a gyro's model: the estimate in the selected model (0 when not kept), the full
// model's estimate and t, and the BIC change from toggling the term in the selected model
// (positive = the selection is preferred).
struct UnitTermStat {
  std::string name, unit;
  bool optional = false, kept = true;
  double estimate = 0, sigma = 0, t = 0, p_value = 1;
  double full_estimate = 0, full_sigma = 0, full_t = 0;
  double delta_bic_toggle = 0;
};

struct UnitCandidate {
  std::vector<std::string> terms;  // optional terms in the model
  double bic = 0;
};

struct GyroCalibration {
  Vec3 nominal_axis = Vec3::UnitX(), axis = Vec3::UnitX();  // body frame, unit vectors
  double bias_dph = 0, scale_factor_ppm = 0, scale_factor_asymmetry_ppm = 0, scale_factor_nonlinearity_ppm_per_dps = 0;
  double temp_dph_per_c = 0, temp_rate_dph_per_c_per_min = 0;
  // Tilts of the fitted axis from the nominal one about the normals u = n x e_min, v = n x u (the
  // convention of GyroErrorModel::misalignment_arcsec): a = (n + mu u + mv v)/|.|.
  double misalignment_arcsec[2] = {0, 0};
  // Covariance of (bias_dph, scale_factor_ppm, misalignment_u_arcsec, misalignment_v_arcsec).
  Eigen::Matrix4d cov = Eigen::Matrix4d::Zero();
  double axis_change_arcsec = 0;  // angle between the fitted and the nominal axis
  std::vector<UnitTermStat> terms;
  std::vector<UnitCandidate> candidates;  // all subsets of the optional terms, best first
  double white_dph = 0;                   // white noise of one sample (first differences)
  double arw_deg_per_sqrt_h = 0;          // the same as angle random walk
  double chi2_per_dof = 0;                // whitened residual of the selected model (1 when the noise model fits)
  double rms_residual_dph = 0;            // of the bin means
};

struct UnitCalibrationResult {
  FitStatus status = FitStatus::kFitted;
  std::string message;
  std::vector<GyroCalibration> gyros;
  bool have_temperature = false;
  double temp_ref_c = 0;
  int n_logs = 0, n_steps = 0, n_bins = 0;
  long n_samples_used = 0;
  double max_rate_dps = 0;
  double reference_condition = 0;  // ratio of the smallest to the largest singular value of the reference rates
  GyroUnit unit;                   // the nominal unit with the fitted terms, calibrated = true
};

// InputError when the logs do not fit the unit or the reference rates do not span 3-D.
UnitCalibrationResult CalibrateUnit(const std::vector<UnitBenchLog>& logs, const GyroUnit& nominal,
                                    const UnitCalibrationOptions& options);

Json UnitCalibrationToJson(const UnitCalibrationResult& r, const UnitCalibrationOptions& options);

}  // namespace ssiu
