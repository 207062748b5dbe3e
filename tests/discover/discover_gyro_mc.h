// Monte Carlo of `DiscoverGyro` on generated cases (shared by the normal test and the long test).
#pragma once

#include <cmath>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "discover/discover_gyro.h"
#include "discover_gyro_generator.h"

namespace ssiu::testing {

struct GyroMcSummary {
  int cases = 0, with_cause = 0, right_cause = 0, clean = 0, clean_none = 0;
  int named = 0, named_gain_above_1 = 0, params_checked = 0, params_within_3_sigma = 0;
  std::map<std::string, std::pair<int, int>> per_cause;  // generator cause -> (right, cases)
  std::map<std::string, int> found;                      // cause found -> cases
};

// One case into the summary (its expected answer is c.cause).
inline void ScoreGyroCase(const std::string& variant, const GyroCase& c, const GyroDiscovery& d, bool verbose,
                          GyroMcSummary* s) {
  ++s->cases;
  ++s->found[d.cause];
  auto& pc = s->per_cause[variant];
  ++pc.second;
  pc.first += d.cause == c.cause;
  if (c.cause == "none") {
    ++s->clean;
    s->clean_none += d.cause == "none";
  } else {
    ++s->with_cause;
    s->right_cause += d.cause == c.cause;
  }
  if (d.cause != "none" && d.cause != "unexplained") {
    ++s->named;
    s->named_gain_above_1 += d.gain > 1;
  }
  std::string params;
  if (d.cause == c.cause) {
    for (const auto& [k, v] : c.truth) {
      if (!d.parameters.count(k)) continue;
      double diff = d.parameters.at(k) - v;
      if (k == "phase_deg") diff = std::remainder(diff, 360.0);
      const double sig = d.sigmas.at(k);
      ++s->params_checked;
      s->params_within_3_sigma += std::abs(diff) <= 3 * sig;
      params += " " + k + "=" + std::to_string(d.parameters.at(k)) + "(" + std::to_string(v) + "+-" +
                std::to_string(sig) + ")";
    }
  }
  if (verbose) {
    std::cout << "case " << variant << " found " << d.cause << " gain " << d.gain << " z " << d.gain_z << params
              << "\n   residual p " << d.residual.p_value << " " << d.residual.finding << " period "
              << d.residual.period_s << " column " << d.residual.follows_column << " partial " << d.partial_cause
              << " jumps " << d.residual.jumps << " (within " << d.residual.levels_within_ratio << ", p "
              << d.residual.jumps_p << ", levels differ " << d.residual.jump_size_dph << " deg/h) shape p "
              << d.residual.periodic_shape_p << " harmonics p " << d.residual.harmonics_p << "\n   levels split p "
              << d.residual.levels_within_p << ", telegraph llr " << d.residual.telegraph_llr << " p "
              << d.residual.telegraph_p << " share " << d.residual.telegraph_share << " (HMM levels "
              << d.residual.telegraph_levels_dph << " deg/h apart, dwell " << d.residual.telegraph_dwell_s
              << " s)\n   variance change p " << d.residual.variance_change_p << " at "
              << d.residual.variance_change_time_s << " s (ratio " << d.residual.variance_ratio << "), outliers "
              << d.residual.outliers << " p " << d.residual.outliers_p << " (largest " << d.residual.outlier_max_sigma
              << " sigma), nonlinear chi2 " << d.residual.nonlinear_chi2 << " (" << d.residual.nonlinear_dof << " dof, "
              << d.residual.nonlinear_term << ") p " << d.residual.nonlinear_p << "\n";
    for (const auto& cand : d.candidates) {
      if (!cand.applicable) continue;
      std::cout << "   " << cand.cause << " stat " << cand.statistic << " p " << cand.p_value;
      if (cand.evaluated)
        std::cout << " gain " << cand.gain << " z " << cand.gain_z << " zb " << cand.gain_z_blocks << " "
                  << cand.verdict;
      std::cout << "\n";
    }
  }
}

// per_cause cases of each cause in `causes` (generator variants), seeds seed0 + 7919 i.
inline GyroMcSummary RunGyroMonteCarlo(const std::vector<std::string>& causes, int per_cause, uint64_t seed0,
                                       bool verbose) {
  GyroMcSummary s;
  int i = 0;
  for (int k = 0; k < per_cause; ++k) {
    for (const auto& cause : causes) {
      const GyroCase c = MakeGyroCase(cause, seed0 + 7919 * i++);
      ScoreGyroCase(cause, c, DiscoverGyro(c.logs, GyroDiscoverOptions{}), verbose, &s);
    }
  }
  return s;
}

// Cases i = 0..n-1 with cause GyroCauses()[i % 9] (so about one in nine is clean).
inline GyroMcSummary RunGyroMonteCarlo(int n, uint64_t seed0, bool verbose) {
  GyroMcSummary s;
  const auto& causes = GyroCauses();
  for (int i = 0; i < n; ++i) {
    const std::string cause = causes[i % causes.size()];
    const GyroCase c = MakeGyroCase(cause, seed0 + 7919 * i);
    ScoreGyroCase(cause, c, DiscoverGyro(c.logs, GyroDiscoverOptions{}), verbose, &s);
  }
  return s;
}

inline void PrintGyroRates(const GyroMcSummary& s) {
  for (const auto& [cause, rc] : s.per_cause) std::cout << "  " << cause << " " << rc.first << "/" << rc.second << "\n";
}

}  // namespace ssiu::testing
