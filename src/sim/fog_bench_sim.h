// Simulated static-bench campaigns of one FOG (thermal runs) and of the FOGX/FOGY pair on a
// turntable (magnetic sensitivity test), as in the SSIU programme's bench calibration. Used by the
// bench-calibration tests, the benchmark and `ssiu simulate fog-thermal|fog-turntable`.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "inertial/fog_error_model.h"

namespace ssiu {

// Earth's sidereal rotation rate, deg/h.
constexpr double kEarthRateDph = 15.041067;

// Projection of the Earth rate on a fixed bench axis at `latitude_deg`: "up" (Omega sin(lat)),
// "down", "north" (Omega cos(lat)), "south", "east"/"west" (0). InputError on another name.
double EarthRateOnAxisDph(double latitude_deg, const std::string& axis);

// One thermal run: a chamber temperature programme of ramps (rates up to max_rate) and dwells
// spanning [temp_min, temp_max], seen through a first-order chamber lag; the FOG drift is the
// ThermalDriftModel of the true T and dT/dt plus a first-order Gauss-Markov bias wander and white
// noise; the temperature channel carries its own white noise.
struct ThermalBenchOptions {
  double duration_s = 700 * 60.0;
  double dt_s = 1.0;
  double temp_min_c = 20.0;
  double temp_max_c = 30.0;
  double min_rate_c_per_min = 0.06;  // programme ramp rates are drawn in [min, max]
  double max_rate_c_per_min = 0.25;
  double dwell_min_s = 15 * 60.0;
  double dwell_max_s = 50 * 60.0;
  double chamber_tau_s = 240.0;  // lag of the FOG housing behind the chamber set point
  double temp_noise_c = 0.02;    // per-sample noise of temp_c
  // Noise sized so that the compensated band of one-minute means is about the paper's +-0.05 deg/h.
  double white_noise_dph = 0.09;    // per-sample (dt_s) white noise of w_dph
  double wander_sigma_dph = 0.006;  // steady-state sigma of the Gauss-Markov bias wander
  double wander_tau_s = 1800.0;
  double latitude_deg = 50.05;  // Kharkov
  std::string axis = "up";
  ThermalDriftModel drift;
  uint64_t seed = 1;
  void Check() const;  // InputError on a bad value
};

struct ThermalBenchRun {
  std::vector<double> t_s, w_dph, ref_dph, temp_c;                       // the logged channels
  std::vector<double> true_temp_c, true_rate_c_per_min, true_drift_dph;  // truth (thermal part)
};

ThermalBenchRun SimulateThermalRun(const ThermalBenchOptions& options);
// t_s,w_dph,ref_dph,temp_c[,true_temp_c,true_rate_c_per_min,true_drift_dph].
void WriteThermalRunCsv(const std::string& path, const ThermalBenchRun& run, bool with_truth = true);

// The campaign's drift: the terms the SSIU paper kept (K00, K10, K01, K03) with values that give an
// uncompensated drift band of about +-1 deg/h over 20-30 C and +-0.25 C/min.
ThermalDriftModel CampaignDriftModel();

// The turntable test (paper eqs. (2)-(3)): `positions` dwells at azimuths 0, step, 2 step, ...
// of the FOGX sensing axis (FOGY's axis is 90 deg behind, so it sees W_phi sin(psi)), with an
// initial azimuth trim error dpsi0, constant drifts, a transient after each turn, and the drift
// caused by the magnetic field (north, east, vertical-down components) through each FOG's
// sensitivities along its axis, across it (horizontal) and vertical.
struct TurntableOptions {
  int positions = 25;
  double step_deg = 15.0;
  double dwell_s = 600.0;
  double turn_s = 20.0;
  double dt_s = 1.0;
  double transient_dph = 0.4;  // offset right after a turn, decaying with transient_tau_s
  double transient_tau_s = 15.0;
  double latitude_deg = 50.05;
  double dpsi0_deg = 0.5;
  double bias_x_dph = 0.3;
  double bias_y_dph = -0.2;
  double bn_ut = 18.0, be_ut = 2.5, bv_ut = 46.0;  // field at Kharkov, microtesla (down positive)
  MagneticSensitivity fog_x, fog_y;
  double white_noise_dph = 0.12;
  double wander_sigma_dph = 0.005;
  double wander_tau_s = 1800.0;
  double temp_c = 22.0;
  uint64_t seed = 1;
  void Check() const;
};

struct TurntableLog {
  std::vector<double> t_s, wx_dph, wy_dph, azimuth_deg, temp_c;
};

TurntableLog SimulateTurntable(const TurntableOptions& options);
// t_s,wx_dph,wy_dph,azimuth_deg,temp_c.
void WriteTurntableCsv(const std::string& path, const TurntableLog& log);

}  // namespace ssiu
