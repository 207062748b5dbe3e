// Bench calibration of a FOG's zero-signal temperature drift (SSIU paper, eq. (1)):
//   dw = sum_{i+j<=3} K_ij Z1^i Z2^j,  Z1 = (T - 20 C)/10 C,  Z2 = (dT/dt)/(0.25 C/min),
// from one or more static runs logged as t_s,w_dph,ref_dph,temp_c. The drift is w - ref.
//
// Pipeline (docs/fog-calibration.md explains the choices):
//  1. T and G = dT/dt from a local cubic least-squares fit (Savitzky-Golay on the actual time
//     stamps) over a window of rate_window_s around each time: noise is averaged, not differenced.
//  2. The drift is averaged into bins of bin_s; the ten regressors are evaluated at bin centres.
//  3. Residual noise model from the full ten-term fit: white + first-order Gauss-Markov (the bias
//     wander), i.e. ARMA(1,1); the data are prewhitened with its Cholesky factor (GLS).
//  4. Correlation left in the whitened residuals shrinks the sample size to n_eff = n / f, with f
//     the Bartlett-weighted integrated autocorrelation (f = (1 + r1)/(1 - r1) for an AR(1)
//     remainder); n_eff is used in the BIC and in the coefficient sigmas.
//  5. All 1024 subsets of the ten terms are scored by BIC; the minimum is kept.
//  6. Validation: with two or more runs, each of the best candidates is refitted leaving one run
//     out and scored on that run (cross-validated RMS).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "calibration/fit_status.h"
#include "core/json.h"
#include "inertial/fog_error_model.h"

namespace ssiu {

struct ThermalRun {
  std::string file;  // for messages
  std::vector<double> t_s, w_dph, ref_dph, temp_c;
};

// Reads t_s,w_dph,temp_c and ref_dph; without a ref_dph column the reference is the Earth rate on
// `axis` at `latitude_deg` (pass NaN latitude to require the column). InputError on a missing
// column, a non-number, unsorted time or fewer than 10 rows.
ThermalRun ReadThermalRun(const std::string& path, double latitude_deg, const std::string& axis);
// Checks a run built in memory (same rules as ReadThermalRun).
void CheckThermalRun(const ThermalRun& run);

struct TemperatureRateOptions {
  double window_s = 300.0;  // full width of the local fit (5 min)
  int order = 3;            // polynomial degree (>= 1); the derivative is exact up to this degree
  void Check() const;
};

// Smoothed temperature (C) and rate (C/min) at times `at_s` from the noisy channel (t_s, temp_c).
struct TemperatureEstimate {
  std::vector<double> temp_c, rate_c_per_min;
};
TemperatureEstimate EstimateTemperatureRate(const std::vector<double>& t_s, const std::vector<double>& temp_c,
                                            const std::vector<double>& at_s, const TemperatureRateOptions& options);

struct ThermalFitOptions {
  double bin_s = 60.0;
  TemperatureRateOptions rate;
  bool prewhiten = true;              // GLS with the fitted white + Gauss-Markov noise model
  bool effective_sample_size = true;  // n_eff from the whitened residuals' autocorrelation
  int max_noise_lag = 60;             // lags (bins) used for the noise model and the effective sample size
  int validate_top = 6;               // candidates (best BIC) scored by leave-one-run-out validation
  void Check() const;
};

struct DriftBand {
  double peak_dph = 0, rms_dph = 0;
};

// One of the ten terms: the full-model estimate, the selected-model estimate (if kept) and the
// BIC change from toggling it in the selected model (positive = the selection is preferred).
struct ThermalTermStat {
  std::string name;
  bool kept = false;
  double estimate_dph = 0, sigma_dph = 0;  // selected model (0 when not kept)
  double full_estimate_dph = 0, full_sigma_dph = 0, full_t = 0;
  double delta_bic_toggle = 0;
};

struct ThermalCandidate {
  std::vector<std::string> terms;
  double bic = 0;
  double cv_rms_dph = -1;  // -1 when not validated (a single run)
};

// Binned drift of one run, before and after compensation (for plots and figures).
struct ThermalRunSeries {
  std::string file;
  std::vector<double> t_min, temp_c, rate_c_per_min, drift_before_dph, drift_after_dph;
  std::vector<double> angle_before_deg, angle_after_deg;  // accumulated integral of the drift
};

struct ThermalEvaluation {
  DriftBand before, after;
  double angle_error_before_deg = 0, angle_error_after_deg = 0;
  double gain = 0;  // before.peak / after.peak
  std::vector<ThermalRunSeries> runs;
};

struct ThermalFitResult {
  FitStatus status = FitStatus::kFitted;  // always fitted (bad input throws)
  std::string message;
  ThermalDriftModel model;  // kept terms only (others 0)
  std::array<double, ThermalDriftModel::kNumTerms> sigma_dph{};
  std::array<bool, ThermalDriftModel::kNumTerms> kept{};
  std::vector<ThermalTermStat> tested;       // all ten
  std::vector<ThermalCandidate> candidates;  // best by BIC, with validation
  bool validation_agrees = true;             // the BIC choice has the lowest CV RMS (within 5 %)
  int n_bins = 0;
  double n_eff = 0;
  double noise_white_dph = 0, noise_wander_dph = 0, noise_wander_tau_s = 0;  // fitted noise model
  double whitened_r1 = 0;         // lag-1 autocorrelation left after prewhitening
  double variance_inflation = 1;  // n / n_eff from the whitened residuals
  ThermalEvaluation evaluation;   // on the fitted runs
};

ThermalFitResult FitThermalDrift(const std::vector<ThermalRun>& runs, const ThermalFitOptions& options);

// Drift before/after applying `model` to runs (binned as in the fit).
ThermalEvaluation EvaluateThermalModel(const std::vector<ThermalRun>& runs, const ThermalDriftModel& model,
                                       const ThermalFitOptions& options);

// Per-sample compensation: w_comp = w - model(T, G) with T, G from the local fit.
struct ThermalCompensation {
  std::vector<double> t_s, w_dph, w_comp_dph, model_dph, temp_c, rate_c_per_min;
};
ThermalCompensation CompensateThermalRun(const ThermalRun& run, const ThermalDriftModel& model,
                                         const TemperatureRateOptions& rate);

// JSON of a fit (the `ssiu fog thermal` output) and the model read back from it.
Json ThermalFitToJson(const ThermalFitResult& fit, const ThermalFitOptions& options);
Json ThermalEvaluationToJson(const ThermalEvaluation& e);
struct ThermalModelFile {
  ThermalDriftModel model;
  TemperatureRateOptions rate;
  double bin_s = 60;
};
ThermalModelFile ThermalModelFromJson(const Json& j, const std::string& file);

}  // namespace ssiu
