// Monte Carlo of `DiscoverGyro` on generated cases (shared by the normal test and the long test).
#pragma once

#include <cmath>
#include <iostream>
#include <string>

#include "analysis/discover_gyro.h"
#include "discover_gyro_generator.h"

namespace ssiu::testing {

struct GyroMcSummary {
  int cases = 0, with_cause = 0, right_cause = 0, clean = 0, clean_none = 0;
  int named = 0, named_gain_above_1 = 0, params_checked = 0, params_within_3_sigma = 0;
};

// Cases i = 0..n-1 with cause GyroCauses()[i % 9] (so about one in nine is clean).
inline GyroMcSummary RunGyroMonteCarlo(int n, uint64_t seed0, bool verbose) {
  GyroMcSummary s;
  const auto& causes = GyroCauses();
  for (int i = 0; i < n; ++i) {
    const std::string cause = causes[i % causes.size()];
    const GyroCase c = MakeGyroCase(cause, seed0 + 7919 * i);
    const GyroDiscovery d = DiscoverGyro(c.logs, GyroDiscoverOptions{});
    ++s.cases;
    if (cause == "none") {
      ++s.clean;
      s.clean_none += d.cause == "none";
    } else {
      ++s.with_cause;
      s.right_cause += d.cause == cause;
    }
    if (d.cause != "none") {
      ++s.named;
      s.named_gain_above_1 += d.gain > 1;
    }
    std::string params;
    if (d.cause == cause) {
      for (const auto& [k, v] : c.truth) {
        if (!d.parameters.count(k)) continue;
        double diff = d.parameters.at(k) - v;
        if (k == "phase_deg") diff = std::remainder(diff, 360.0);
        const double sig = d.sigmas.at(k);
        ++s.params_checked;
        s.params_within_3_sigma += std::abs(diff) <= 3 * sig;
        params += " " + k + "=" + std::to_string(d.parameters.at(k)) + "(" + std::to_string(v) + "+-" +
                  std::to_string(sig) + ")";
      }
    }
    if (verbose) {
      for (const auto& [k, v] : c.truth) std::cout << "truth " << k << " " << v << "\n";
      std::cout << "case " << i << " true " << cause << " found " << d.cause << " gain " << d.gain << params << "\n";
      for (const auto& cand : d.candidates) {
        if (cand.applicable) std::cout << "   " << cand.cause << " stat " << cand.statistic << " p " << cand.p_value << " dbic " << cand.delta_bic << "\n";
      }
    }
  }
  return s;
}

}  // namespace ssiu::testing
