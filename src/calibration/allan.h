// Overlapping Allan deviation of a gyro rate log with confidence intervals, and the fit of the IEEE
// Std 952-1997 / 1554-2005 noise terms (quantisation Q, angle random walk N, bias instability B, rate
// random walk K, rate ramp R) to such a curve, each with its uncertainty and the tau range supporting it.
//
// Units: the library is linear in the rate unit u of its input (SI, rad/s, when called from the CLI).
// ADEV is in u; the terms are Q [u*s], N [u*sqrt(s)], B [u], K [u/sqrt(s)], R [u/s].
#pragma once

#include <cstddef>
#include <ostream>
#include <string>
#include <vector>

#include "calibration/fit_status.h"

namespace ssiu {

// The power-law noise that governs the statistics of one Allan point (IEEE 952 Annex C naming; the
// frequency-stability names of NIST SP 1065 in brackets).
enum class AllanNoise {
  kQuantization,    // [white phase]  avar ~ tau^-2
  kWhiteRate,       // [white FM]     avar ~ tau^-1, angle random walk
  kFlickerRate,     // [flicker FM]   avar ~ tau^0,  bias instability
  kRandomWalkRate,  // [random-walk FM] avar ~ tau^+1, rate random walk (and, for edf, rate ramp)
};
const char* AllanNoiseName(AllanNoise noise);
inline std::ostream& operator<<(std::ostream& os, AllanNoise v) { return os << AllanNoiseName(v); }

struct AllanOptions {
  int points_per_decade = 10;  // density of the log-spaced tau grid (averaging factors m are integers)
  double confidence = 0.683;   // two-sided confidence level of adev_lo..adev_hi (0.683 = 1 sigma)
  size_t min_samples = 16;     // fewer rate samples than this is bad input
  void Check() const;          // InputError on a bad value
};

// An Allan-deviation curve, computed from a log or read from a file.
struct AllanCurve {
  double sample_rate_hz = 0;  // 0 when unknown
  size_t n = 0;               // rate samples behind the curve; 0 when unknown
  std::vector<double> tau_s;
  std::vector<double> adev;     // in the input rate unit
  std::vector<double> adev_lo;  // confidence interval, same unit
  std::vector<double> adev_hi;
  std::vector<double> edf;        // equivalent degrees of freedom of each Allan variance
  std::vector<AllanNoise> noise;  // noise type assumed for edf at each point
  std::string edf_source;         // "formula", "file", "rel_error" or "assumed"
};

// Overlapping Allan deviation (IEEE Std 952-1997 Annex C; NIST SP 1065, overlapping ADEV) of equally spaced
// rate samples, with chi-squared confidence intervals from the equivalent degrees of freedom of
// Howe, Allan & Barnes (1981) as tabulated in NIST SP 1065 Table 5. The noise type at each tau is
// identified from the local log-log slope of the curve. The caller validates input files;
// InputError on too few samples, a non-finite sample or a bad rate.
AllanCurve OverlappingAllanDeviation(const std::vector<double>& rate, double sample_rate_hz,
                                     const AllanOptions& options = {});

// Equivalent degrees of freedom of an overlapping Allan variance with averaging factor m from
// n_phase = (rate samples + 1) phase points (NIST SP 1065 Table 5, after Howe, Allan & Barnes 1981).
double OverlappingAvarEdf(AllanNoise noise, double n_phase, double m);

// OverlappingAvarEdf, but never above the white-rate value (used for curves, where a noise type
// identified from a noisy slope must not inflate the confidence).
double ConservativeAvarEdf(AllanNoise noise, double n_phase, double m);

// Noise type per point from the local slope of log(avar) against log(tau).
std::vector<AllanNoise> IdentifyNoiseBySlope(const std::vector<double>& tau_s, const std::vector<double>& adev);

// Fills adev_lo/adev_hi from adev and edf at the given two-sided confidence level.
void SetConfidenceIntervals(AllanCurve* curve, double confidence);

// Quantile of the chi-squared distribution with `dof` (real, > 0) degrees of freedom.
double ChiSquaredQuantile(double p, double dof);
// Upper tail P(X > x) of the chi-squared distribution with `dof` (real, > 0) degrees of freedom.
double ChiSquaredSurvival(double x, double dof);

// One fitted noise coefficient.
struct NoiseTerm {
  double value = 0;          // coefficient (units in the header comment); 0 when the fit excluded it
  double sigma = 0;          // 1-sigma uncertainty
  double tau_min_s = 0;      // tau range where this term carries >= `dominance` of the model variance
  double tau_max_s = 0;      //   (both 0 when it dominates nowhere)
  double max_fraction = 0;   // largest share of the model Allan variance this term carries on the curve
  bool significant = false;  // dominant at two or more points (of edf >= support_min_edf) and value > 2 sigma
};

struct NoiseFitOptions {
  bool fit_quantization = true;
  bool fit_bias_instability = true;
  bool fit_rate_ramp = true;
  double tau_min_s = 0;  // fit only the points with tau in [tau_min_s, tau_max_s] (0 = no limit)
  double tau_max_s = 0;
  double dominance = 0.5;     // share of the model variance for a term to "support" a tau
  int iterations = 6;         // reweighting passes (weights from the model, not the noisy data)
  double model_error = 0.02;  // relative ADEV error floor added to each point's statistical error
  double floor_min_edf = 10;  // the curve's floor (adev_min) is sought among points with this edf
  // A term is significant only where it dominates two points with at least this edf (when the curve has
  // any): the last octaves of a log hold a few independent clusters, and a white-noise curve scatters
  // there by tens of percent (chi^2 with 2-5 dof); counted as support, they made a flicker floor or a
  // rate random walk out of white noise in 7-13 % of logs (docs/allan.md).
  double support_min_edf = 10;
  double term_penalty = -1;  // chi-squared cost of each term in model selection; < 0 = ln(effective points)
  void Check() const;
};

struct NoiseFit {
  FitStatus status = FitStatus::kTooFewPoints;
  std::string message;
  NoiseTerm quantization;      // Q
  NoiseTerm arw;               // N
  NoiseTerm bias_instability;  // B
  NoiseTerm rrw;               // K
  NoiseTerm rate_ramp;         // R
  double chi2_per_dof = 0;     // of the final weighted fit (points treated as independent)
  size_t points_used = 0;
  double adev_min = 0;  // floor of the curve (see floor_min_edf) and its tau: B = adev_min / 0.664
  double tau_at_min_s = 0;
  double adev_min_sigma = 0;             // its 1-sigma from the point's edf
  bool adev_min_is_upper_bound = false;  // the curve still falls (white noise) at its floor
  std::vector<double> model_adev;        // the fitted model at the curve's taus
  // The fitted model's Allan deviation at tau (IEEE 952 Annex C model without the sinusoidal term).
  double ModelAdev(double tau_s) const;
};

// Weighted non-negative least squares of avar(tau) = 3Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3
// + R^2 tau^2/2 (IEEE 952 Annex C) to a curve; weights from each point's edf, each point counted for
// its share of an octave since overlapping estimates closer than that are strongly correlated.
// Works on any curve with tau_s, adev and edf (from a log or read from a file).
NoiseFit FitNoiseTerms(const AllanCurve& curve, const NoiseFitOptions& options = {});

}  // namespace ssiu
