// The term-selection Monte Carlo shared by fog_thermal_test (small) and fog_thermal_longtest (100).
#pragma once

#include <sstream>
#include <string>

#include "calibration/fog_thermal.h"
#include "core/rng.h"
#include "sim/fog_bench_sim.h"

namespace ssiu {

struct ThermalMcSummary {
  int cases = 0;
  int exact_selection = 0;  // kept terms == true terms
  int kept_coefficients = 0;
  int within_3sigma = 0;  // kept coefficients within 3 sigma of truth
  double coefficients_within_3sigma_fraction = 0;
  int cases_all_within_3sigma = 0;
  std::string failures;
  std::string Describe() const {
    std::ostringstream s;
    s << "cases " << cases << ", exact selection " << exact_selection << ", kept coefficients within 3 sigma "
      << within_3sigma << "/" << kept_coefficients << ", cases with all within 3 sigma " << cases_all_within_3sigma
      << failures;
    return s.str();
  }
};

// Random true subsets (each term present with probability 0.4, |K| in [0.25, 0.8] deg/h, random
// sign), two 700-minute runs each with the campaign's noise and bias wander.
inline ThermalMcSummary RunThermalSelectionMc(int cases, uint64_t seed0,
                                              const ThermalFitOptions& options = ThermalFitOptions{}) {
  ThermalMcSummary s;
  Rng rng(seed0);
  for (int c = 0; c < cases; ++c) {
    ThermalBenchOptions o;
    int nterms = 0;
    while (nterms == 0) {
      for (int k = 0; k < ThermalDriftModel::kNumTerms; ++k) {
        o.drift.k_dph[k] = 0;
        if (rng.Uniform() < 0.4) {
          o.drift.k_dph[k] = rng.Uniform(0.25, 0.8) * (rng.Uniform() < 0.5 ? -1 : 1);
          ++nterms;
        }
      }
    }
    std::vector<ThermalRun> runs;
    for (int r = 0; r < 2; ++r) {
      o.seed = seed0 + 1000 * c + r;
      const ThermalBenchRun sim = SimulateThermalRun(o);
      runs.push_back({"mc", sim.t_s, sim.w_dph, sim.ref_dph, sim.temp_c});
    }
    const ThermalFitResult fit = FitThermalDrift(runs, options);
    bool exact = true, all_in = true;
    std::ostringstream why;
    for (int k = 0; k < ThermalDriftModel::kNumTerms; ++k) {
      const bool truth = o.drift.k_dph[k] != 0;
      if (fit.kept[k] != truth) {
        exact = false;
        why << " " << ThermalDriftModel::TermName(k) << (truth ? " missed" : " extra");
      }
      if (fit.kept[k]) {
        ++s.kept_coefficients;
        const double z = (fit.model.k_dph[k] - o.drift.k_dph[k]) / fit.sigma_dph[k];
        if (std::abs(z) <= 3) {
          ++s.within_3sigma;
        } else {
          all_in = false;
          why << " " << ThermalDriftModel::TermName(k) << " z=" << z;
        }
      }
    }
    ++s.cases;
    s.exact_selection += exact;
    s.cases_all_within_3sigma += all_in;
    if (!exact || !all_in) s.failures += "\n  case " + std::to_string(c) + ":" + why.str();
  }
  s.coefficients_within_3sigma_fraction = s.kept_coefficients ? double(s.within_3sigma) / s.kept_coefficients : 1.0;
  return s;
}

}  // namespace ssiu
