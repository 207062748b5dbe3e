// Internal to `ssiu discover gyro`: the design, the noise model, the candidates' fits and the residual
// tests shared by discover_gyro*.cc (method in discover_gyro.h).
#pragma once

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "core/types.h"
#include "discover/discover_gyro.h"

namespace ssiu::discover_internal {

using Eigen::MatrixXd;
using Eigen::VectorXd;

// Candidate regressor columns (bin means), in this fixed order.
// kBn..kBh: the logged field (uT); kAbsRef: |ref| * 1e-6, which with kScale splits the scale factor of
// positive and negative rates; kLag: Z1 of the temperature through the first-order lag that thermal_lag's
// scan located (discover_gyro_lag.h), never in the full model (the noise models stay those of the others).
enum Col { kT1, kT2, kG1, kMagSin, kMagCos, kBn, kBe, kBh, kMis, kScale, kAbsRef, kDelay, kLag, kNumCols };

struct LogBins {
  double bin_s = 0, temp_span_c = 0;
  std::array<double, 3> field_span_ut{0, 0, 0};  // range of the bin means of bn, be, bh
  std::vector<double> t_s, y_dph;
  std::vector<std::array<double, kNumCols>> x;
  std::map<std::string, std::vector<double>> column_mean;  // bin means of the logged columns (residual test)
  // Bin means of nonlinear functions of the logged reference (NonlinearChi2): the azimuth's second
  // harmonic on a log with an azimuth (its reference is Earth rate x cos psi, a function of the
  // azimuth), else ref^2, |ref|, ref^3 of the reference scaled to its largest |value|.
  std::map<std::string, std::vector<double>> nonlinear_mean;
  // A spectral line above the bins' band (SpectralLineTest, on the raw samples): tested when the log is
  // evenly sampled and its bins hold >= 12 samples; its p (over the log's ordinates), frequency, amplitude.
  bool line_tested = false;
  double line_p = 1, line_frequency_hz = 0, line_amplitude_dph = 0, line_power_ratio = 0;
  std::vector<int> sample_bin;  // per sample of the log: its bin (index into t_s)
};

// White + first-order Gauss-Markov noise of one log (autocovariance gamma_0 = w + g,
// gamma_k = g phi^k), optionally plus a random walk of the bias (variance q per bin), and the
// exact whitening by the innovations of its Kalman filter (states: wander x, walk level b; with a
// walk, b starts diffuse, so the log's constant bias is absorbed).
struct NoiseModel {
  double var_w = 1, var_g = 0, phi = 0, q_rw = 0;
  bool diffuse_level = false;  // b starts diffuse even without a walk (the likelihood of the null)
  bool known_level = false;    // b starts at 0 exactly, even with a walk (TelegraphInWanderLogLik)
  std::vector<Eigen::Vector2d> gain;
  std::vector<double> inv_sqrt_s;  // per bin

  static constexpr double kDiffuse = 1e6;  // prior variance of b relative to the noise, with a walk

  // The filter's gains and innovation variances for m bins.
  void Prepare(int m);
  // Whitened copy of v (length m): innovation / sqrt(S_k).
  VectorXd Whiten(const VectorXd& v) const;
  // The same recursion on n series of length m at once (in[c] -> out[c]), bit for bit Whiten's on each:
  // the series' dependency chains interleave, which is what makes it faster. From bin `from` on, when
  // every series is zero before it (the filter's state is then zero there; out is left as it is before).
  void WhitenSeries(const double* const* in, double* const* out, int n, int m, int from = 0) const;
  // Whiten() of every column of x.
  MatrixXd WhitenCols(const MatrixXd& x) const;
  // Gaussian negative log-likelihood of v, leaving out the first (diffuse) innovation.
  double NegLogLik(const VectorXd& v) const;
};

// A noise model fitted by maximum likelihood (FitNoiseMle), its negative log-likelihood and the walk's ln-sigma.
struct NoiseMle {
  NoiseModel model;
  double nll = 0, ln_q_sigma = 0;
};

struct LsFit {
  VectorXd beta;
  MatrixXd cov_unscaled;  // (X^T X)^-1
  double rss = 0;
  bool ok = false;
};

struct Design {
  std::vector<LogBins> bins;
  std::vector<int> offset;  // first row of each log
  int n = 0;
  MatrixXd cols;  // n x kNumCols raw regressors
  VectorXd y;
  // n x (L + k): the per-log bias indicators, then the columns of the causes named at earlier steps of the
  // stepwise extension (DiscoverGyro); every candidate is tested against this base model.
  MatrixXd base;
  // thermal_lag's located time constant, the scan's independent positions and d(kLag column)/d(tau) (raw).
  double lag_tau_s = 0;
  int lag_positions = 0;
  VectorXd lag_dtau;
};

// A candidate of the vocabulary made of regressor columns: `cols` that are usable are fitted; it is
// applicable when every column of `required` is usable and at least one column is left.
struct CandidateSpec {
  std::string cause, model;
  std::vector<int> cols, required;
};

struct CvResult {
  double rms_before = 0, rms_after = 0;
  double z = 0;         // significance of the held-out improvement, largest over logs
  double z_blocks = 0;  // the same from the blocks' own scatter (paired over the blocks), largest over logs
};

// The whitened residual wr (each log's whitened bias projected out: a GLS residual) regressed on log r's
// nonlinear functions of the logged reference (LogBins::nonlinear_mean), whitened with the same noise
// models and with the bias projected out: chi^2 = explained sum of squares / s2 with dof = rank; the
// joint GLS coefficients (dph per unit of each function) and the single function of largest chi^2.
struct NonlinearFit {
  double chi2 = 0;
  int dof = 0;
  std::string term;
  std::map<std::string, double> coefficients;
};

// Deterministic shapes in time of log r (FixedColumnsChi2 on fixed columns of the bin time): a trend
// (Legendre P1, P2 over the log jointly: ageing, a rate ramp) or a transient from the log's start,
// exp(-(t - t_start) / tau) alone (a warm-up after switch-on; the bin's mean of it), tau on the grid 600 2^j s up
// to a quarter of the log; the best shape's p-value Bonferroni-corrected for the number of shapes (nearly
// collinear, so conservative). The vocabulary's slow causes follow a logged column (temperature, dT/dt, field) or
// are random (rate_random_walk) or a step; a shape that is a fixed function of time is none of them.
struct TimeShapeFit {
  NonlinearFit fit;
  double p = 1, log_p = 0, tau_s = 0;
};

// The scan's statistic at one step position; rho_prev: the correlation of its whitened step with that of the
// position before it on the same log (kNoNeighbour for a log's first position).
struct StepPoint {
  static constexpr double kNoNeighbour = -2;
  int log;
  double t_s, w, rho_prev = kNoNeighbour;
};

// The located step of `bias_step`: the best over the scans so far (best_step keeps an earlier pass's
// when no position beats zero), the positions tried and the profile of the last scan.
struct StepScan {
  VectorXd best_step;
  double best_step_t = 0, best_w = 0;
  int positions = 0, best_step_log = 0;
  std::vector<StepPoint> profile;
};

// ln of the p-value of a step scan's largest statistic w over the positions of `profile`.
double StepScanLogP(const std::vector<StepPoint>& profile, double w);

// The located sinusoid of `periodic_drift` (kept across passes as StepScan's step).
struct PeriodicScan {
  VectorXd best_sin, best_cos;
  double best_freq = 0, best_pw = 0, positions = 0;
  int best_periodic_log = 0;
};

// rate_random_walk on the long logs (walk_logs): the candidate, the noise models with the walk (nm_walk,
// the others' as nm), the walk strength's ln-sigma and log of the most significant log, the summed
// negative log-likelihood.
struct WalkTest {
  GyroCandidate candidate;
  std::vector<NoiseModel> nm_walk;
  double lnq_sigma = 1, nll = 0;
  int log = 0;
};

// A candidate's fit: GLS, raw design, columns, the inflation it was scored with.
struct Fitted {
  LsFit gls;
  MatrixXd x;             // raw (unwhitened) design of base + cause
  std::vector<int> cols;  // its Col columns (empty for the located ones)
  double inflation = 1;
};

// The normalisation of a candidate's statistic: the whitened drift, the base model's GLS residual sum of
// squares, the full model's residual variance and the inflation of its whitened residuals.
struct ScoreNorm {
  VectorXd y_w;
  double base_rss = 0, s2 = 1, infl = 1;
};

// 5. A candidate's parameters with their sigmas, its held-out gain, and whether the parameters lie
// within the physical bounds.
struct Evaluation {
  std::map<std::string, double> parameters, sigmas;
  CvResult cv;
  std::string out_of_bounds;  // empty when within the bounds
};

// A cause named at one step of the stepwise extension (DiscoverGyro): its columns join the base model of
// the next step; the scans that located it and its step's noise models are kept for the joint fit.
struct NamedCause {
  GyroCandidate candidate;
  Evaluation ev;                // at the step it entered, against the model before it
  std::vector<int> cols;        // its Col columns
  std::vector<VectorXd> extra;  // located: the step, or the sinusoid's sin and cos
  StepScan step_scan;
  PeriodicScan periodic_scan;
  std::vector<NoiseModel> nm, nm_walk;  // the step's noise models (nm_walk: with rate_random_walk's walk)
  double position_cost = 0;             // ln(positions scanned) when located (its BIC's cost)
};

// One step: every candidate not yet named against the current base model (d.base), the significant ones
// in BIC order through the gates; the first that passes is named. alpha and gain_alpha are the step's.
struct GyroStep {
  std::vector<GyroCandidate> candidates;
  bool named = false;
  NamedCause cause;
  std::vector<NoiseModel> nm;
  double inflation = 1, alpha_each = 0, z_min = 0;
  int periodic_log = 0;  // the log of the scan's best sinusoid
};

// thermal_lag's time constant must differ from 0 by this many sigma (its gates and NarrowLag).
constexpr double kLagMinTauZ = 3;

// A BIC difference below this is "not worth more than a bare mention" (Kass & Raftery 1995, Bayes factors,
// JASA 90 p. 777, on 2 ln B, which the BIC difference approximates): the walk and lag chains of RunChain and
// the look-ahead of BicOrder do not act on less.
constexpr double kBareMentionBic = 2;

// The verdict of a walk or lag that the chain run again without it matched (discover_gyro.cc's RunChain).
inline constexpr char kChainWithoutIt[] =
    "the causes named without it have a BIC (exact likelihood) below or within 2 of its";

// discover_gyro.cc
std::vector<GyroRival> StepRivals(const NamedCause& nc, const std::vector<GyroCandidate>& candidates);

// discover_gyro_log.cc
Design BuildDesign(const std::vector<GyroBenchLog>& logs, const GyroDiscoverOptions& o);
std::vector<int> UsableColumns(Design* design, const GyroDiscoverOptions& o, std::vector<bool>* usable_out,
                               std::vector<double>* scale_out);

// discover_gyro_noise.cc
NoiseMle FitNoiseMle(const VectorXd& v, double bin_s, double tau_max_s, const NoiseModel& start, bool with_walk,
                     int iters = 600);
NoiseModel FitNoise(const VectorXd& e, int max_lag, double phi_max);
LsFit SolveLs(const MatrixXd& x, const VectorXd& y);
VectorXd LevelResidual(const Design& d);
MatrixXd Assemble(const Design& d, const std::vector<int>& which, const std::vector<VectorXd>& extra);
MatrixXd WhitenRows(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& x);
double VarianceInflation(const Design& d, const VectorXd& ew, int lag_max);
NoiseMle FitWalkMle(const VectorXd& v, double bin_s, double tau_max_s, const NoiseModel& h0);
void RefitResidualNoise(const Design& d, const GyroDiscoverOptions& o, const VectorXd& e_fit,
                        std::vector<NoiseModel>* noise_fit);
NoiseModel FitNoiseReml(const VectorXd& y, const MatrixXd& x, double bin_s, double tau_max_s, const NoiseModel& start);
void FitLogNoise(const Design& d, const GyroDiscoverOptions& o, const MatrixXd& x_full, const VectorXd& e_ols,
                 std::vector<NoiseModel>* nm, std::vector<double>* log_var);
void ReportLongestLogNoise(const Design& d, const std::vector<NoiseModel>& nm, GyroDiscovery* res);

// discover_gyro_causes.cc
void BinSinusoid(const LogBins& b, double fr, VectorXd* sn, VectorXd* cs);
std::pair<double, double> GoldenSectionMax(const std::function<double(double)>& fn, double lo, double hi, int iters);
std::pair<double, double> ScanSinusoid(const LogBins& b, const NoiseModel& noise, const VectorXd& cw,
                                       const VectorXd& rr, double norm, double f_lo, double f_hi);
std::string Key(const GyroCandidate& c);
void ScanStep(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& bw, const VectorXd& base_res,
              double sigma2_f, StepScan* sc);
void ScanPeriodic(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& bw, const VectorXd& base_res,
                  const GyroDiscoverOptions& o, int pass, double sigma2_f, PeriodicScan* sc);
WalkTest TestRandomWalk(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm,
                        const std::vector<int>& walk_logs, double alpha_each, double n_eff);
std::vector<int> SpecColumns(const CandidateSpec& sp, const std::vector<bool>& usable);
ScoreNorm MakeScoreNorm(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& noise,
                        const MatrixXd& x_full);
std::vector<GyroCandidate> TestCandidates(const Design& d, const GyroDiscoverOptions& o,
                                          const std::vector<NoiseModel>& noise, const MatrixXd& x_full,
                                          const std::vector<CandidateSpec>& specs, const std::vector<bool>& usable,
                                          double alpha_each, const StepScan& step_scan,
                                          const PeriodicScan& periodic_scan, std::map<std::string, Fitted>* fits,
                                          std::map<std::string, double>* position_cost);
double FittedBic(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm, const MatrixXd& x,
                 int dof, double cost);
double CandidateBic(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm,
                    const GyroCandidate& c, const std::vector<int>& walk_logs, double walk_nll,
                    std::map<std::string, Fitted>* fits, const std::map<std::string, double>& position_cost);
void EvaluateWalk(const Design& d, const GyroDiscoverOptions& o, const std::vector<int>& walk_logs,
                  const std::vector<double>& log_var, double q, int walk_log, double walk_lnq_sigma, Evaluation* ev);
void EvaluateFitted(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm, const Fitted& fit,
                    const std::string& cause, const std::vector<double>& scale, const StepScan& step_scan,
                    const PeriodicScan& periodic_scan, Evaluation* ev);

// discover_gyro_gates.cc
double BlockZ(const std::vector<double>& block_sums);
CvResult CrossValidate(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& x_cause, int blocks);
GyroStep RunGyroStep(const Design& d, const GyroDiscoverOptions& o, const std::vector<bool>& usable,
                     const std::vector<double>& scale, const std::vector<int>& full_cols,
                     const std::set<std::string>& excluded, double alpha, double gain_alpha,
                     const std::string& first_file);

// discover_gyro_jumps.cc
double JumpsTest(const Design& d, const std::vector<NoiseModel>& nm, const VectorXd& e, const GyroDiscoverOptions& o,
                 GyroResidual* res);

// discover_gyro_residual.cc
NonlinearFit FixedColumnsChi2(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& bw,
                              const VectorXd& wr, int r, double s2,
                              const std::map<std::string, std::vector<double>>& fns);
NonlinearFit NonlinearChi2(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& bw, const VectorXd& wr,
                           int r, double s2);
double LogChi2Survival(double x, double k);
double LogCandidateP(const GyroCandidate& c);
std::vector<std::pair<std::map<std::string, std::vector<double>>, double>> TimeShapes(const LogBins& b);
MatrixXd TrendColumns(const LogBins& b);
TimeShapeFit TimeShapeChi2(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& bw, const VectorXd& wr,
                           int r, double s2);
GyroResidual TestResidual(const Design& d, const std::vector<NoiseModel>& nm, const VectorXd& e,
                          const GyroDiscoverOptions& o, double fundamental_hz = 0, int fundamental_log = 0);

// misalignment (the azimuth harmonic at the Earth rate's phase) or magnetic_field (a harmonic of free
// phase), which are the same regressor where the field's phase lies near the misalignment's: the field when
// its Bayes factor wins at even prior odds. With the harmonic's sin and cos estimated with equal Gaussian
// errors sigma, both amplitudes uniform over one range and the field's phase uniform, Laplace's
// approximation of each evidence gives B(misalignment : field) = exp(-extra_chi2 / 2) sqrt(pi / 2) A / sigma
// (A / sigma = sqrt(harmonic_chi2), the free harmonic's chi^2 against the model without it; extra_chi2
// its chi^2 against the misalignment). The field is named when B < 1: a threshold of 3-6 on extra_chi2 for
// a harmonic 4-15 sigma strong, where a test of the phase at alpha = 0.01 asks 6.6 at every strength.
// FieldPhaseExtraChi2Even: the extra chi^2 at which B = 1; 2 ln B(misalignment : field) is it minus extra_chi2.
inline double FieldPhaseExtraChi2Even(double harmonic_chi2) {
  return std::log(kPi / 2) + std::log(std::max(harmonic_chi2, 1.0));
}
inline bool FieldPhaseWarranted(double extra_chi2, double harmonic_chi2) {
  return extra_chi2 > FieldPhaseExtraChi2Even(harmonic_chi2);
}

// Two causes of which one is the other with a constraint (they share columns): misalignment / magnetic_field's
// azimuth harmonic, scale_factor / scale_factor_asymmetry.
inline bool NestedPair(const std::string& a, const std::string& b) {
  return (a == "misalignment" && b == "magnetic_field") || (a == "magnetic_field" && b == "misalignment") ||
         (a == "scale_factor" && b == "scale_factor_asymmetry") ||
         (a == "scale_factor_asymmetry" && b == "scale_factor");
}

// A nested cause's wider partner is taken (Upgrade at a step, WidenNested in the final model): misalignment's
// (magnetic_field) when FieldPhaseWarranted, scale_factor's (scale_factor_asymmetry) when the extra term's
// chi^2 (extra_dof) is significant at alpha. wide_chi2: the wider one's chi^2 against the model without either.
bool WiderWarranted(const std::string& nested_cause, double extra_chi2, double wide_chi2, int extra_dof, double alpha);

}  // namespace ssiu::discover_internal
