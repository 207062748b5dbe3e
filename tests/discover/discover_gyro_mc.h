// Monte Carlo of `DiscoverGyro` on generated cases (shared by the normal test and the long test).
#pragma once

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "discover/discover_gyro.h"
#include "discover_gyro_generator.h"

namespace ssiu::testing {

struct GyroMcSummary {
  int cases = 0, with_cause = 0, right_cause = 0, clean = 0, clean_none = 0;
  int named = 0, named_gain_above_1 = 0, params_checked = 0, params_within_3_sigma = 0;
  int chain_extra = 0;  // cases whose chain of named causes (d.causes) holds more than one
  std::map<std::string, std::pair<int, int>> per_cause;  // generator cause -> (right, cases)
  std::map<std::string, int> found;                      // cause found -> cases
};

// The true parameters (truth) against the estimates (par, sig) that have them: counts those checked and
// those within 3 sigma (phases modulo 360 deg), and appends "prefix name=estimate(truth+-sigma)" to *out.
inline void CheckParameters(const std::string& prefix, const std::map<std::string, double>& truth,
                            const std::map<std::string, double>& par, const std::map<std::string, double>& sig,
                            int* checked, int* within, std::string* out) {
  for (const auto& [k, v] : truth) {
    if (!par.count(k)) continue;
    double diff = par.at(k) - v;
    if (k == "phase_deg") diff = std::remainder(diff, 360.0);
    ++*checked;
    *within += std::abs(diff) <= 3 * sig.at(k);
    *out += " " + prefix + k + "=" + std::to_string(par.at(k)) + "(" + std::to_string(v) + "+-" +
            std::to_string(sig.at(k)) + ")";
  }
}

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
  s->chain_extra += d.causes.size() > 1;  // one hidden cause at most: a second named one is spurious
  if (d.cause != "none" && d.cause != "unexplained") {
    ++s->named;
    s->named_gain_above_1 += d.gain > 1;
  }
  std::string params;
  if (d.cause == c.cause) {
    CheckParameters("", c.truth, d.parameters, d.sigmas, &s->params_checked, &s->params_within_3_sigma, &params);
  }
  if (verbose) {
    std::string chain;
    for (const auto& n : d.causes) chain += " " + n.cause;
    std::cout << "case " << variant << " found " << d.cause << " [" << chain << " ] gain " << d.gain << " z "
              << d.gain_z << params << "\n   residual p " << d.residual.p_value << " " << d.residual.finding
              << " period " << d.residual.period_s << " column " << d.residual.follows_column << " partial "
              << d.partial_cause << " jumps " << d.residual.jumps << " (within " << d.residual.levels_within_ratio
              << ", p " << d.residual.jumps_p << ", levels differ " << d.residual.jump_size_dph << " deg/h) shape p "
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

// Several hidden causes at once (the stepwise extension): a case counts as both named when every hidden
// cause is in d.causes and the verdict is not `unexplained`; a wrong cause is a named cause that was not
// hidden. Parameters: each hidden cause's truth against the joint fit's values and sigmas.
struct GyroMultiSummary {
  int cases = 0, all_named = 0, wrong = 0, unexplained = 0, params_checked = 0, params_within_3_sigma = 0;
  // The ties reported (GyroNamedCause::rivals): cases with a wrong cause where every hidden cause left out is
  // a rival of a named one; cases with both named where some named cause has a rival.
  int wrong_hidden_rival = 0, all_named_with_rival = 0;
  std::map<std::string, std::pair<int, int>> per_combo;  // "a + b" -> (all named, cases)
};

// One case's outcome as GyroMultiSummary counts it: every hidden cause named and the verdict not
// `unexplained`; some named cause that was not hidden.
struct GyroMultiOutcome {
  bool all_named = false, wrong = false;
};
inline GyroMultiOutcome ScoreGyroMultiOutcome(const GyroCase& c, const GyroDiscovery& d) {
  int found = 0;
  GyroMultiOutcome out;
  for (const auto& n : d.causes) {
    const bool hidden = std::find(c.causes.begin(), c.causes.end(), n.cause) != c.causes.end();
    found += hidden;
    out.wrong = out.wrong || !hidden;
  }
  out.all_named = found == static_cast<int>(c.causes.size()) && d.cause != "unexplained";
  return out;
}

inline void ScoreGyroMulti(const GyroCase& c, const GyroDiscovery& d, bool verbose, GyroMultiSummary* s) {
  ++s->cases;
  std::string combo, chain;
  for (const auto& h : c.causes) combo += (combo.empty() ? "" : " + ") + h;
  for (const auto& n : d.causes) chain += (chain.empty() ? "" : " + ") + n.cause;
  std::string params;
  for (const auto& n : d.causes) {
    if (std::find(c.causes.begin(), c.causes.end(), n.cause) == c.causes.end() || !c.truths.count(n.cause)) continue;
    CheckParameters(n.cause + ".", c.truths.at(n.cause), n.parameters, n.sigmas, &s->params_checked,
                    &s->params_within_3_sigma, &params);
  }
  const GyroMultiOutcome outcome = ScoreGyroMultiOutcome(c, d);
  const bool all = outcome.all_named, wrong = outcome.wrong;
  s->all_named += all;
  s->wrong += wrong;
  std::set<std::string> named_or_rival;
  std::string rivals;
  bool any_rival = false;
  for (const auto& n : d.causes) {
    named_or_rival.insert(n.cause);
    for (const auto& r : n.rivals) {
      named_or_rival.insert(r.cause), any_rival = true;
      rivals += " " + r.cause + " for " + n.cause + " (" + std::to_string(r.delta_bic) + ")";
    }
  }
  bool hidden_covered = true;
  for (const auto& h : c.causes) hidden_covered = hidden_covered && named_or_rival.count(h);
  s->wrong_hidden_rival += wrong && hidden_covered;
  s->all_named_with_rival += all && any_rival;
  s->unexplained += d.cause == "unexplained";
  auto& pc = s->per_combo[combo];
  pc.first += all, ++pc.second;
  if (verbose) {
    std::cout << "case " << combo << ": " << d.cause << " [" << chain << "]" << params << "\n   residual p "
              << d.residual.p_value << " " << d.residual.finding << "\n";
    if (any_rival) std::cout << "   rivals:" << rivals << "\n";
    for (size_t k = 0; k < d.later_steps.size() + 1; ++k) {
      for (const auto& cand : k == 0 ? d.candidates : d.later_steps[k - 1]) {
        // the first step: its significant candidates; later ones: every candidate (how near a weak cause came)
        if (!cand.applicable || (!cand.significant && k == 0)) continue;
        std::cout << "   step " << k + 1 << " " << cand.cause << " p " << cand.p_value;
        if (cand.evaluated) std::cout << " gain " << cand.gain << " z " << cand.gain_z << " " << cand.verdict;
        std::cout << "\n";
      }
    }
  }
}

// Every unordered pair of `causes`.
inline std::vector<std::vector<std::string>> GyroCausePairs(const std::vector<std::string>& causes) {
  std::vector<std::vector<std::string>> out;
  for (size_t i = 0; i < causes.size(); ++i) {
    for (size_t j = i + 1; j < causes.size(); ++j) out.push_back({causes[i], causes[j]});
  }
  return out;
}

// per_combo cases of each combination, seeds seed0 + 7919 i.
inline GyroMultiSummary RunGyroMultiMonteCarlo(const std::vector<std::vector<std::string>>& combos, int per_combo,
                                               uint64_t seed0, bool verbose) {
  GyroMultiSummary s;
  int i = 0;
  for (int k = 0; k < per_combo; ++k) {
    for (const auto& combo : combos) {
      const GyroCase c = MakeGyroCase(combo, seed0 + 7919 * i++);
      ScoreGyroMulti(c, DiscoverGyro(c.logs, GyroDiscoverOptions{}), verbose, &s);
    }
  }
  return s;
}

// The size of an effect outside the vocabulary, as the field of the case's model that carries it (nullptr for
// an effect without one size).
inline double* LeftoverSize(GyroCaseModel& m, const std::string& effect) {
  if (effect == "chirp") return &m.chirp_amp;
  if (effect == "sawtooth") return &m.saw_amp;
  if (effect == "square_wave_column") return &m.heater_amp;
  if (effect == "telegraph") return &m.tele_amp;
  if (effect == "azimuth_second_harmonic") return &m.az2_amp;
  if (effect == "linear_trend") return &m.trend_dph;
  return nullptr;
}

// The case of `effect` (out of the vocabulary; beside the vocabulary's cause `partner` unless empty) with the
// effect scaled so that its RMS over the static log (its mean removed) is k times the noise of one of the
// library's bins there (the white noise averaged over the bin width, and the Gauss-Markov wander). The effect
// is measured, not modelled: the static log with the effect at its drawn size less the same log without it
// (the effects draw from streams of their own, so the noise is the same sample for sample).
inline GyroCase ScaledLeftoverCase(const std::string& effect, const std::string& partner, double k, uint64_t seed) {
  std::vector<std::string> causes = {effect};
  if (!partner.empty()) causes.push_back(partner);
  double drawn = 0, noise_dph = 0;
  const GyroCase with = MakeGyroCase(causes, seed, false, [&](GyroCaseModel& m) {
    drawn = *LeftoverSize(m, effect);
    const double bin_s = 43200.0 / GyroDiscoverOptions{}.max_bins_per_log;
    noise_dph = std::hypot(m.arw / std::sqrt(bin_s), m.gm);
  });
  const GyroCase without = MakeGyroCase(causes, seed, false, [&](GyroCaseModel& m) { *LeftoverSize(m, effect) = 0; });
  const std::vector<double>&a = with.logs[0].w_dph, &b = without.logs[0].w_dph;
  double mean = 0, ss = 0;
  for (size_t i = 0; i < a.size(); ++i) mean += (a[i] - b[i]) / a.size();
  for (size_t i = 0; i < a.size(); ++i) ss += std::pow(a[i] - b[i] - mean, 2);
  const double scale = k * noise_dph / std::sqrt(ss / a.size());
  return MakeGyroCase(causes, seed, false, [&](GyroCaseModel& m) { *LeftoverSize(m, effect) = drawn * scale; });
}

}  // namespace ssiu::testing
