// Magnetic sensitivity test of the horizontal FOG pair on a turntable (SSIU paper, eqs. (2)-(4)).
// The unit dwells at N azimuths psi_i of the FOGX axis; the mean outputs minus the nominal Earth
// rate give the error functions
//   f_x(psi) = W_X - W_phi cos(psi) = dW_x + S_x sin(psi + phi_x),
//   f_y(psi) = W_Y - W_phi sin(psi) = dW_y + S_y cos(psi + phi_y),
// fitted by linear least squares as dW + E_1 cos(psi) + E_2 sin(psi) per axis. The 2x2 harmonic
// matrix E = [[E_x1, E_x2], [E_y1, E_y2]] splits into a conformal part (rotation + scale: what an
// azimuth trim error dpsi0 produces, S_x = -S_y and phi_x = phi_y) and an anti-conformal part
// (c, d) that a trim error cannot produce: its size is the magnetic measure. The magnetic error is
// what remains of E after removing the trim rotation, W_phi (R(dpsi0) - I).
// Note: a magnetic term acting as a pure rotation (equal and opposite cross-sensitivities) is
// indistinguishable from a trim error and is absorbed into dpsi0.
#pragma once

#include <string>
#include <vector>

#include "calibration/fit_status.h"
#include "core/json.h"

namespace ssiu {

struct TurntableData {
  std::string file;
  std::vector<double> t_s, wx_dph, wy_dph, azimuth_deg;
};

// Reads t_s,wx_dph,wy_dph,azimuth_deg (temp_c and other columns are ignored). InputError on a
// missing column, a non-number or unsorted time.
TurntableData ReadTurntableLog(const std::string& path);

struct MagneticOptions {
  double latitude_deg = 50.05;    // Kharkov
  double settle_s = 60.0;         // excluded after the table stops at a new azimuth
  double min_dwell_s = 60.0;      // a dwell shorter than this (after settling) is dropped
  double azimuth_tol_deg = 0.01;  // azimuth steadier than this = the table is at rest
  int min_positions = 8;          // distinct azimuths needed (3 parameters per axis + dof)
  // Slow bias wander of the FOGs (first-order Gauss-Markov, e.g. from their Allan deviation). The
  // azimuth advances with time, so wander aliases into the harmonics; the fit is GLS with this
  // covariance on top of the white part measured within each dwell. 0 = white noise only.
  double wander_sigma_dph = 0.005;
  double wander_tau_s = 1800.0;
  void Check() const;
};

struct DwellMean {
  double azimuth_deg = 0, t_start_s = 0, t_end_s = 0, wx_dph = 0, wy_dph = 0;
  double var_mean_x = 0, var_mean_y = 0;  // variance of the means from the within-dwell scatter
  int samples = 0;
};

struct AxisHarmonicFit {
  double dw_dph = 0, dw_sigma_dph = 0;
  double s_dph = 0, s_sigma_dph = 0;  // signed amplitude, phase kept within +-90 deg
  double phi_deg = 0, phi_sigma_deg = 0;
  double e_cos_dph = 0, e_sin_dph = 0;  // f = dw + e_cos cos(psi) + e_sin sin(psi)
  double residual_rms_dph = 0;
  double variance_inflation = 1;  // chi^2/dof of the GLS fit when above 1
};

struct MagneticResult {
  FitStatus status = FitStatus::kFitted;  // always fitted (bad input throws)
  std::string file;
  std::vector<DwellMean> dwells;
  double w_phi_dph = 0;
  AxisHarmonicFit x, y;
  double dpsi0_deg = 0, dpsi0_sigma_deg = 0;
  double scale_departure_dph = 0, scale_departure_sigma_dph = 0;    // |conformal part| - W_phi
  double anticonformal_c_dph = 0, anticonformal_d_dph = 0;          // (E_x1 - E_y2)/2, (E_x2 + E_y1)/2
  double magnetic_measure_dph = 0, magnetic_measure_sigma_dph = 0;  // hypot(c, d): departure from S_x = -S_y
  double magnetic_amplitude_x_dph = 0, magnetic_amplitude_y_dph = 0;
  double magnetic_amplitude_dph = 0, magnetic_amplitude_sigma_dph = 0;  // max of the two axes
  double magnetic_chi2 = 0;          // of (c, d, scale departure) against zero, 3 degrees of freedom
  bool consistent_with_zero = true;  // chi2 below its 99.73 % point (14.16)
};

MagneticResult FitMagneticSensitivity(const TurntableData& log, const MagneticOptions& options);

// Error functions of a fit at azimuth psi (deg): f_x, f_y and their magnetic parts.
struct MagneticCurves {
  std::vector<double> psi_deg, fx_dph, fy_dph, mag_x_dph, mag_y_dph;
};
MagneticCurves MagneticFitCurves(const MagneticResult& fit, int points = 361);

Json MagneticResultToJson(const MagneticResult& fit);

}  // namespace ssiu
