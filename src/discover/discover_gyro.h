// Model discrepancy of single-axis gyro bench logs (`ssiu discover gyro`, docs/discrepancy.md):
// start from the base model (a constant bias per log + white noise + slow bounded wander), test each
// candidate cause of the fixed vocabulary (conventions.md) against it, name the best significant one
// or `none`, fit it and measure the gain on data the fit did not see.
//
// Method:
//  1. Each log t_s,w_dph,ref_dph,temp_c[,azimuth_deg] is averaged into at most max_bins_per_log bins;
//     the drift is y = w - ref. Regressors per bin (linear, so bin means are exact):
//       temperature K10, K20 (Z1, Z1^2), temperature_gradient K01 (Z2), with T and dT/dt from the
//       local-polynomial estimate of fog_thermal.h; magnetic_field S sin(psi + phi) as
//       (sin psi, cos psi); misalignment delta * d(ref)/d(psi) (a fixed-phase harmonic, nested in
//       the magnetic one); scale_factor ref * 1e-6 (ppm); time_delay -d(ref)/dt (seconds).
//  2. The noise of the full model (every applicable regressor) is fitted as white + first-order
//     Gauss-Markov by REML under the full model's columns (a slow wander is not read as weaker for what
//     those columns absorb; started from the ARMA(1,1) autocovariance fit of fog_thermal) and the data are whitened
//     exactly (GLS) by the innovations of its Kalman filter. Correlation left in the whitened residuals shrinks the
//     sample size to n_eff = n / f (Bartlett-weighted integrated autocorrelation).
//  3. Each candidate: Wald chi^2 of its terms against the base model (q <= 2 dof), scaled by f;
//     `bias` (a step in the bias) is located by a scan and its p-value is the tail of the scan's maximum
//     (James, James & Siegmund 1987, capped by the Hunter-Worsley bound over neighbouring positions);
//     A candidate is significant when p < alpha / (number of candidates tested).
//     rate_random_walk is the likelihood ratio of the base noise model plus a random walk of the
//     bias against the base noise model, both fitted by maximum likelihood (Kalman filter).
//  4. Among the significant candidates the lowest exact-likelihood BIC wins (noise model refitted
//     by maximum likelihood on the residual of each), so that steps, walks and slow regressors
//     compete on the same footing.
//     New in issue 18: bias_step (the located step, formerly reported as `bias`), periodic_drift (a
//     located sinusoid: GLS periodogram, Bonferroni over independent frequencies),
//     scale_factor_asymmetry (ref and |ref|), magnetic_field from the logged bn/be/bh columns.
//     thermal_lag (discover_gyro_lag.h): the temperature through a first-order lag, its time constant
//     located by a scan; named only when the lag is significant against none and its held-out RMS is
//     below temperature's and temperature_gradient's.
//  4b. Gates, in BIC order until one passes: the parameters lie within physical bounds (temperature
//     and field must move; K, ppm, delay, amplitude limits; no cancelling terms; a walk needs >= 1 h)
//     and the held-out improvement is significant: z = e.p / sqrt(p' S p) (e held-out base residual,
//     p held-out prediction, S the fitted noise covariance) above the one-sided quantile of gain_alpha,
//     and seen in the held-out blocks' own scatter too (paired block z > min_block_z).
//  4c. `unexplained`: the residual of the named cause (or of the base) is whitened with a noise model
//     refitted on it and tested (spectral peak, Ljung-Box, runs, regression on every logged column, and
//     jumps: the likelihood ratio of a telegraph carrying a share of the wander against the noise model,
//     calibrated by a bootstrap of the noise model (a level that switches between two values); a change of the noise
//     level (CUSUM of squares), outliers (generalized ESD) and nonlinear functions of the reference (ref^2,
//     |ref|, ref^3; the azimuth's second harmonic) and shapes in time (a trend, a warm-up); weighted
//     Bonferroni over the nine at residual_alpha; a candidate that a function of the reference or a shape in
//     time explains as well is not named;
//     after periodic_drift also its harmonics / folded shape, a test of the sinusoid of its own); structure left ->
//     `unexplained`, the residual described (period, amplitude, the column it follows, the jumps) and the first cause
//     kept as partial_cause.
//  5. Gain: each log is cut into cv_blocks blocks; the model is fitted on the even blocks and scored
//     on the odd ones and vice versa (bin RMS of the drift after a bias-only fit / after the cause).
//     For rate_random_walk: one-step prediction of the bins of the second half of each log by a
//     constant bias vs an exponentially smoothed level tuned on the first half.
//  7. Stepwise extension (issue 31): the named cause's columns join the base model and steps 1-5 are redone
//     against it (one GLS of the biases + every cause named so far), each step at alpha 2^-s (step s from 0),
//     until no candidate passes; with two causes a shape in time must beat a candidate together with its best
//     partner, and a walk ranked first goes last when two deterministic candidates beat it in BIC. A step
//     that names rate_random_walk or thermal_lag (each can stand for other causes) is weighed against the
//     chain run again from there without it, by the exact-likelihood BIC of the two chains' models; the
//     chain without it is kept unless it is worse by more than 2 (Kass & Raftery 1995's bare mention). With
//     several named, the step and the sinusoid are located again and a nested cause (misalignment,
//     scale_factor) is weighed against its wider partner in the final model. The residual test (4c) then
//     runs on the final joint model. `cause` stays the first named; `causes` lists the chain with the joint
//     fit's parameters (docs/discrepancy.md).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "calibration/fog_thermal.h"
#include "core/json.h"

namespace ssiu {

struct GyroBenchLog {
  std::string file;
  std::vector<double> t_s, w_dph, ref_dph, temp_c, azimuth_deg;  // azimuth empty when absent
  std::vector<double> bn_ut, be_ut, bh_ut;  // logged magnetic field (north, east, vertical); empty when absent
  // Every other numeric column (name -> values): the residual is tested against each (`unexplained`).
  std::map<std::string, std::vector<double>> other;
};

// Reads t_s,w_dph,ref_dph,temp_c[,azimuth_deg][,bn_ut,be_ut,bh_ut]; other all-numeric columns go to
// `other`. InputError on a missing column, a non-number, unsorted time or fewer than 50 rows.
GyroBenchLog ReadGyroBenchLog(const std::string& path);
void CheckGyroBenchLog(const GyroBenchLog& log);

struct GyroDiscoverOptions {
  double alpha = 0.01;             // family-wise false-alarm probability over all candidates
  int max_bins_per_log = 1000;     // bin width = max(sample interval, duration / this)
  TemperatureRateOptions rate;     // T and dT/dt estimation
  int max_noise_lag = 30;          // bins used for the noise model and the effective sample size
  double wander_tau_max_s = 1800;  // the base model's wander is bounded with correlation time <= this
  int cv_blocks = 32;              // per log, for the cross-validated gain
  // Gates (docs/discrepancy.md): a cause is named only when its held-out improvement is significant
  // at gain_alpha (one-sided, Bonferroni over logs) and its parameters lie within the physical bounds.
  double gain_alpha = 0.01;
  // ... and the same improvement judged by the scatter of the held-out blocks themselves (paired over
  // the cv_blocks blocks, no noise model) must exceed this many of its standard errors: a consistency
  // check of the modelled z, not a second test (docs/discrepancy.md).
  double min_block_z = 0.5;
  double min_temp_span_c = 1.0;    // temperature terms are tested only when T moves at least this much
  double min_field_span_ut = 1.0;  // a logged field component is a regressor only when it moves this much
  double rrw_min_log_s = 3600;     // a random walk is tested only on logs at least this long
  double periodic_min_cycles = 3;  // a periodic drift must repeat at least this often within its log
  // `unexplained`: the residual of the named cause (or of the base model) is tested against the
  // fitted noise model; family-wise false-alarm probability of the residual tests.
  double residual_alpha = 0.01;
  int residual_lags = 10;  // Ljung-Box lags (bins)
  void Check() const;
};

struct GyroCandidate {
  std::string cause;
  std::string model;     // when a cause has several: magnetic_field "azimuth_harmonic" or "logged_field"
  double statistic = 0;  // Wald chi^2 (deterministic, bias) or likelihood ratio (rate_random_walk)
  double p_value = 1;
  double delta_bic = 0;  // BIC(base) - BIC(base + cause) under the GLS whitening; > 0 favours the cause
  double bic = 0;        // exact-likelihood BIC (noise refitted), significant candidates only; lowest wins
  int dof = 0;
  bool applicable = true;  // false when the logs cannot show it (e.g. no azimuth column)
  bool significant = false;
  // Gates, for the significant candidates tried in BIC order until one passes.
  bool evaluated = false;
  double gain = 0, gain_z = 0;  // held-out gain and its significance (z of the improvement)
  double gain_z_blocks = 0;     // the same z from the held-out blocks' own scatter (no noise model)
  std::string verdict;          // "named", "gain not significant", "outside bounds: ...", ...
};

// A logged column against the residual (whitened GLS regression, per-log means removed).
struct GyroResidualColumn {
  std::string column;
  double chi2 = 0, p_value = 1;
  double coefficient_dph_per_unit = 0, correlation = 0;
};

// The residual after the best cause (or the base model) against the fitted noise model.
struct GyroResidual {
  bool structured = false;  // significant at residual_alpha over the tests
  double p_value = 1;       // family-wise (weighted Bonferroni over the nine tests; or the harmonics test's own)
  // The most significant test: spectral_peak, autocorrelation, runs, column, jumps, variance_change,
  // outliers, nonlinearity, harmonics.
  std::string finding;
  double rms_dph = 0;
  double period_s = 0, amplitude_dph = 0, spectral_chi2 = 0, spectral_p = 1;  // strongest sinusoid
  double ljung_box_q = 0, ljung_box_p = 1;
  int ljung_box_lags = 0;
  double runs_z = 0, runs_p = 1;
  std::string follows_column;  // the most significant logged column
  double column_coefficient = 0, column_correlation = 0, column_p = 1;
  std::vector<GyroResidualColumn> columns;
  double harmonics_p = 1, harmonic_period_s = 0;  // periodic_drift's 2nd/3rd harmonics (when it was fitted)
  // periodic_drift's shape: the residual folded at its period into phase bins (a sawtooth is not a sinusoid).
  double periodic_shape_chi2 = 0, periodic_shape_p = 1;
  int periodic_shape_dof = 0;
  // Jumps of the level between two values (a telegraph bias), in the log where they are most significant:
  // the levels of the pieces of constant level (binary segmentation) split into two groups, the
  // within-group share of their variance; the likelihood ratio of a telegraph carrying a share of the
  // wander against the noise model (the test's statistic; jumps_p its bootstrap p-value, Bonferroni over
  // logs); and a two-state hidden Markov model's levels and dwell.
  int jumps = 0;                                                   // switches between the two groups
  double levels_within_ratio = 1, jumps_p = 1, jump_size_dph = 0;  // split's statistic, test's p, levels apart
  double levels_within_p = 1;                 // the level split's bootstrap p-value on the same replicates (that log)
  double telegraph_llr = 0, telegraph_p = 1;  // ln L(telegraph in wander) - ln L(noise model) (nats), its p
  double telegraph_share = 0;                 // the share of the wander's variance the telegraph carries there
  double telegraph_levels_dph = 0, telegraph_dwell_s = 0;  // the HMM's levels apart and mean dwell
  std::vector<double> jump_times_s;
  // Variance change (CUSUM of squares, most significant log): statistic, p (Bonferroni over logs), the
  // change time and the variance after / before it.
  double variance_change_stat = 0, variance_change_p = 1, variance_change_time_s = 0, variance_ratio = 1;
  // Outliers (generalized ESD): how many, when, the largest in standard deviations, p (over logs).
  int outliers = 0;
  double outlier_max_sigma = 0, outliers_p = 1;
  std::vector<double> outlier_times_s;
  // Nonlinear functions of the logged reference (ref^2, |ref|, ref^3; the azimuth's second harmonic): the
  // most significant log's chi^2, dof, its function of largest chi^2 and the joint coefficients (dph per
  // unit: ref scaled to its largest |value|, the harmonic's sin/cos), p (Bonferroni over logs).
  double nonlinear_chi2 = 0, nonlinear_p = 1;
  int nonlinear_dof = 0;
  std::string nonlinear_term;
  std::map<std::string, double> nonlinear_coefficients_dph;
  // Shapes in time (a trend: Legendre P1, P2 over the log; a warm-up exp(-t/tau) from the log's start): the
  // most significant log's chi^2, dof, its function of largest chi^2 alone, the joint coefficients (dph per
  // unit), the warm-up's tau (0 when the log is too short for one), p (over the tau grid and the logs).
  double trend_chi2 = 0, trend_p = 1, warm_up_tau_s = 0;
  int trend_dof = 0;
  std::string trend_term;
  std::map<std::string, double> trend_coefficients_dph;
  // A spectral line above the bins' band (raw samples of an evenly sampled log whose bins hold >= 12 of
  // them, e.g. a vibration pickup on a 100 Hz rate-table log): p (over the ordinates and the logs), the
  // line's frequency and sinusoid amplitude, its power over the local noise level.
  double line_p = 1, line_frequency_hz = 0, line_amplitude_dph = 0, line_power_ratio = 0;
};

// A cause the data support about as well as a named one in its place, the other named causes fitted:
// delta_bic is the model's BIC with the rival in its place minus the BIC with the named cause (exact
// likelihood, noise refitted; for the nested pair misalignment / magnetic_field, 2 ln of the Bayes factor
// that chooses between them, the quantity the BIC difference approximates). Listed when below 2, "not worth
// more than a bare mention" (Kass & Raftery 1995); negative when the rival's BIC is lower and the step's
// order (its look-ahead) or a gate passed the named one first.
struct GyroRival {
  std::string cause, model;
  double delta_bic = 0;
};

// A cause of the stepwise extension (issue 31), in the order the causes entered the model.
struct GyroNamedCause {
  std::string cause, model;
  // From the final joint fit (one GLS of the biases + every named cause); a walk's from its own step.
  std::map<std::string, double> parameters, sigmas;
  double gain = 1, gain_z = 0;                   // held-out, at the step it entered (against the model before it)
  double rms_before_dph = 0, rms_after_dph = 0;  // held-out bin RMS before / after that step
  std::vector<GyroRival> rivals;                 // the ties the data do not break, lowest delta_bic first
};

// The correlation r of two coefficients of different named causes in the joint fit ("cause.coefficient").
struct GyroCorrelation {
  std::string a, b;
  double r = 0;
};

struct GyroDiscovery {
  // The FIRST named cause (or none / unexplained): the contract's field. `causes` holds the chain.
  std::string cause = "none";
  // The first cause's: names of the FOG calibration issue (K10_dph, amplitude_dph, ...); from the joint fit
  // when several causes were named.
  std::map<std::string, double> parameters;
  std::map<std::string, double> sigmas;                    // 1-sigma of each parameter (same keys)
  double rms_before_dph = 0, rms_after_dph = 0, gain = 1;  // cross-validated, held-out bins
  double gain_z = 0, gain_z_min = 0;      // significance of the held-out improvement and the gate on it
  std::vector<GyroCandidate> candidates;  // the first step's
  // Stepwise extension: the named causes in order, the correlations of their coefficients (|r| > 0.3,
  // between different causes) and the candidates of each later step (step 2, 3, ...; the last named none).
  std::vector<GyroNamedCause> causes;
  std::vector<GyroCorrelation> correlations;
  std::vector<std::vector<GyroCandidate>> later_steps;
  // `unexplained`: the cause that was fitted before the residual test found structure left.
  std::string partial_cause;
  GyroResidual residual;
  // Evidence: noise model and sample sizes.
  int n_bins = 0;
  double n_eff = 0, variance_inflation = 1;
  double noise_white_dph = 0, noise_wander_dph = 0, noise_wander_tau_s = 0;
  double alpha_per_candidate = 0;
};

GyroDiscovery DiscoverGyro(const std::vector<GyroBenchLog>& logs, const GyroDiscoverOptions& options);

Json GyroDiscoveryToJson(const GyroDiscovery& d);

}  // namespace ssiu
