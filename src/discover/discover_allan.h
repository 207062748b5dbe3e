// Where ssiu's default gyro noise model departs from a measured Allan curve (docs/discrepancy.md).
// The default model of the simulator (inertial/gyro_unit.h GyroErrorModel) is white rate noise
// (ARW) plus a bias-instability floor, no rate random walk, no quantisation, no ramp. It is fitted
// to the curve (weighted least squares of avar = N^2/tau + (2 ln2/pi) B^2, IEEE 952 eq. C.13,
// weights from each point's edf); the tau ranges where it leaves the curve's confidence interval
// by more than `sigmas` are reported, and the extended model is the full IEEE 952 fit of allan.h
// (FitNoiseTerms), whose significant extra terms name what was missing.
// Stepwise extension (issue 31): the terms the default model lacks (quantization, rate_random_walk,
// rate_ramp) are added one at a time to ARW + B, the one of largest significant held-out gain first,
// every term refitted jointly at each step, until none passes; the final model then fits the curve
// (`none` left) or still departs from it (`unexplained`, the departing tau ranges given).
#pragma once

#include <string>
#include <vector>

#include "calibration/allan.h"
#include "core/json.h"

namespace ssiu {

struct AllanDiscrepancyOptions {
  double sigmas = 3.0;  // a point departs when |model - adev| > sigmas * its 1-sigma
  // Stepwise extension: family-wise false-alarm probability of the first step's terms (step s: 2^-s of it)
  // and the one-sided false-alarm probability of the held-out gain's gate.
  double alpha = 0.01;
  double gain_alpha = 0.05;
  void Check() const;
};

// A term added by the stepwise extension, in the order the terms entered.
struct AllanStepTerm {
  std::string term;             // quantization, rate_random_walk, rate_ramp
  double value = 0, sigma = 0;  // final joint fit, curve's unit (Q: u s, K: u / sqrt(s), R: u / s)
  double p_value = 1;           // its chi^2 test at the step it entered
  double gain = 1, gain_z = 0;  // held-out at that step: RMS of the held-out points' normalised residuals
                                // before / after, and the paired z of that improvement
  double chi2_per_dof = 0;      // of the model after that step
  double residual_rms_pct = 0;  // RMS of model adev / adev - 1 after that step (%), points weighted by
                                // their precision (adev / 1-sigma)^2
};

// The correlation r of two coefficients (squared terms) of the final joint fit, |r| > 0.3, one of them named.
struct AllanCorrelation {
  std::string a, b;
  double r = 0;
};

struct AllanDiscrepancy {
  double base_arw = 0, base_bias_instability = 0;          // in the curve's unit (N: u sqrt(s), B: u)
  double chi2_per_dof_before = 0, chi2_per_dof_after = 0;  // points weighted as in FitNoiseTerms' error model
  std::vector<std::pair<double, double>> departures_s;     // tau ranges [lo, hi] where the base departs
  std::vector<std::string> missing_terms;                  // significant extra terms of the full fit
  NoiseFit extended;
  std::vector<double> base_adev;  // at the curve's taus
  // Stepwise extension: the terms named in order, the final joint fit (ARW, B and the named terms with their
  // 1-sigmas, curve's unit; the others 0), the correlations, and what is left: "none" or "unexplained"
  // (the final model's departures).
  std::vector<AllanStepTerm> steps;
  double residual_rms_pct_before = 0;  // as AllanStepTerm's, of ARW + B fitted as the steps are
  double residual_rms_pct_after = 0;   // of the final model (the last step's, or ARW + B when none)
  double point_sigma_rms_pct = 0;      // the points' own 1-sigma / adev (%), averaged alike: what a fit reaches
  NoiseFit joint;
  std::vector<AllanCorrelation> correlations;
  std::string left = "none";
  std::vector<std::pair<double, double>> final_departures_s;
  std::vector<double> final_adev;  // the final model at the curve's taus
};

AllanDiscrepancy CompareAllanToDefaultModel(const AllanCurve& curve, const AllanDiscrepancyOptions& options);

}  // namespace ssiu
