// Where ssiu's default gyro noise model departs from a measured Allan curve (docs/discrepancy.md).
// The default model of the simulator (inertial/gyro_unit.h GyroErrorModel) is white rate noise
// (ARW) plus a bias-instability floor, no rate random walk, no quantisation, no ramp. It is fitted
// to the curve (weighted least squares of avar = N^2/tau + (2 ln2/pi) B^2, IEEE 952 eq. C.13,
// weights from each point's edf); the tau ranges where it leaves the curve's confidence interval
// by more than `sigmas` are reported, and the extended model is the full IEEE 952 fit of allan.h
// (FitNoiseTerms), whose significant extra terms name what was missing.
#pragma once

#include <string>
#include <vector>

#include "calibration/allan.h"
#include "core/json.h"

namespace ssiu {

struct AllanDiscrepancyOptions {
  double sigmas = 3.0;  // a point departs when |model - adev| > sigmas * its 1-sigma
  void Check() const;
};

struct AllanDiscrepancy {
  double base_arw = 0, base_bias_instability = 0;          // in the curve's unit (N: u sqrt(s), B: u)
  double chi2_per_dof_before = 0, chi2_per_dof_after = 0;  // points weighted as in FitNoiseTerms' error model
  std::vector<std::pair<double, double>> departures_s;     // tau ranges [lo, hi] where the base departs
  std::vector<std::string> missing_terms;                  // significant extra terms of the full fit
  NoiseFit extended;
  std::vector<double> base_adev;  // at the curve's taus
};

AllanDiscrepancy CompareAllanToDefaultModel(const AllanCurve& curve, const AllanDiscrepancyOptions& options);

}  // namespace ssiu
