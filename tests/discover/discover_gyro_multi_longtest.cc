// Acceptance of the stepwise extension of `ssiu discover gyro` (issue 31): logs with two hidden causes
// together, every pair of six causes (temperature, temperature_gradient, magnetic_field, bias_step,
// periodic_drift, scale_factor) drawn four times (60 cases; docs/discrepancy.md records the figures), the
// misses weighed by the criterion and the outcomes by the weaker hidden cause's strength.
#include <algorithm>
#include <cmath>
#include <set>

#include "discover/discover_gyro_internal.h"
#include "discover_gyro_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using namespace discover_internal;

// Positions a located term's scan tries (its BIC cost is ln of them, as the library's): the step at every
// bin boundary of 5 %..95 % of each log, the sinusoid's independent frequencies (range x duration) on the
// logs of >= 24 bins.
double StepPositions(const Design& d) {
  double n = 0;
  for (const auto& b : d.bins) {
    const int m = static_cast<int>(b.t_s.size());
    n += std::max(0, m - m / 20 - std::max(1, m / 20));
  }
  return n;
}
double PeriodicPositions(const Design& d, const GyroDiscoverOptions& o) {
  double n = 0;
  for (const auto& b : d.bins) {
    const double dur = b.t_s.back() - b.t_s.front() + b.bin_s;
    const double f_lo = o.periodic_min_cycles / dur, f_hi = 0.25 / b.bin_s;
    if (b.t_s.size() >= 24 && f_hi > f_lo) n += (f_hi - f_lo) * dur;
  }
  return n;
}

// The deterministic model of `causes` (regressor columns and located terms) on the biases: the hidden ones
// with the generator's step time and period, the named ones with those the discovery reports. A step and a
// sinusoid are columns of the static log (log 0), where the generator puts them. *cost: ln of the located
// terms' scanned positions, as the library's BIC counts them. False for a cause that is not regressor
// columns (rate_random_walk).
bool ModelColumns(const Design& d, const GyroDiscoverOptions& o, const std::vector<std::string>& causes,
                  const std::map<std::string, std::map<std::string, double>>& par, std::vector<int>* cols,
                  std::vector<VectorXd>* extra, double* cost) {
  const int m = static_cast<int>(d.bins[0].t_s.size());
  const double t0 = d.bins[0].t_s.front() - 0.5 * d.bins[0].bin_s;
  for (const auto& k : causes) {
    if (k == "temperature") {
      cols->insert(cols->end(), {kT1, kT2});
    } else if (k == "temperature_gradient") {
      cols->push_back(kG1);
    } else if (k == "thermal_lag") {
      cols->push_back(kLag), *cost += std::log(std::max(1, d.lag_positions));
    } else if (k == "magnetic_field") {
      cols->insert(cols->end(), {kMagSin, kMagCos});
    } else if (k == "misalignment") {
      cols->push_back(kMis);
    } else if (k == "scale_factor") {
      cols->push_back(kScale);
    } else if (k == "bias_step") {
      VectorXd v = VectorXd::Zero(d.n);
      for (int i = 0; i < m; ++i) v(i) = d.bins[0].t_s[i] - t0 >= par.at(k).at("step_time_s") ? 1 : 0;
      extra->push_back(v), *cost += std::log(StepPositions(d));
    } else if (k == "periodic_drift") {
      VectorXd s = VectorXd::Zero(d.n), c = VectorXd::Zero(d.n);
      const double w = 2 * kPi / par.at(k).at("period_s");
      for (int i = 0; i < m; ++i)
        s(i) = std::sin(w * (d.bins[0].t_s[i] - t0)), c(i) = std::cos(w * (d.bins[0].t_s[i] - t0));
      extra->push_back(s), extra->push_back(c), *cost += std::log(PeriodicPositions(d, o));
    } else {
      return false;
    }
  }
  return true;
}

// The BIC of the exact likelihood (FittedBic, the criterion the chain's order and its walk and lag chains
// use, under the first step's noise models nm) of the biases + `causes` (ModelColumns).
bool ModelBic(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm,
              const std::vector<std::string>& causes, const std::map<std::string, std::map<std::string, double>>& par,
              double* bic) {
  std::vector<int> cols;
  std::vector<VectorXd> extra;
  double cost = 0;
  if (!ModelColumns(d, o, causes, par, &cols, &extra, &cost)) return false;
  *bic = FittedBic(d, o, nm, Assemble(d, cols, extra), static_cast<int>(cols.size() + extra.size()), cost);
  return true;
}

// How strong each hidden cause is, apart from the noise drawn: the signal the generator put in (its true
// parameters times the cause's columns; EvaluateFitted's parameters inverted) whitened with the noise left
// once every hidden cause is fitted (each log's noise model refitted by maximum likelihood on the hidden
// model's GLS residual under nm: the first step's models, fitted without the located terms, take a periodic
// drift or a step for wander) and projected off the biases and the other hidden causes, as a number of
// sigmas: z^2 is the non-centrality of the cause's chi^2 with the others fitted (its expected chi^2 is
// z^2 + its dof). The weaker cause's z of a case sets what any test of it can see. NaN for a cause it
// cannot weigh (not one of the six causes of the pairs).
double WeakerHiddenZ(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm0,
                     const std::vector<double>& scale, const testing::GyroCase& c) {
  std::vector<int> hc;
  std::vector<VectorXd> he;
  double unused = 0;
  if (!ModelColumns(d, o, c.causes, c.truths, &hc, &he, &unused)) return std::nan("");
  const MatrixXd xh = Assemble(d, hc, he);
  const LsFit gh = SolveLs(WhitenRows(d, nm0, xh), WhitenRows(d, nm0, d.y));
  const VectorXd e = d.y - xh * gh.beta;
  std::vector<NoiseModel> nm;
  for (size_t r = 0; r < d.bins.size(); ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    nm.push_back(FitNoiseMle(e.segment(d.offset[r], m), d.bins[r].bin_s, o.wander_tau_max_s, nm0[r], false).model);
  }
  double z_min = 1e9;
  for (const auto& k : c.causes) {
    std::vector<std::string> others;
    for (const auto& j : c.causes) {
      if (j != k) others.push_back(j);
    }
    std::vector<int> oc, kc;
    std::vector<VectorXd> oe, ke;
    if (!ModelColumns(d, o, others, c.truths, &oc, &oe, &unused) ||
        !ModelColumns(d, o, {k}, c.truths, &kc, &ke, &unused)) {
      return std::nan("");
    }
    const auto& t = c.truths.at(k);
    std::vector<double> coef;  // per column of kc then ke
    if (k == "temperature") coef = {t.at("K10_dph") * scale[kT1], t.at("K20_dph") * scale[kT2]};
    if (k == "temperature_gradient") coef = {t.at("K01_dph") * scale[kG1]};
    if (k == "scale_factor") coef = {t.at("scale_factor_ppm") * scale[kScale]};
    if (k == "bias_step") coef = {t.at("step_dph")};
    if (k == "magnetic_field" || k == "periodic_drift") {
      const double a = t.at("amplitude_dph"), ph = t.at("phase_deg") * kDegToRad;
      const double us = k == "magnetic_field" ? scale[kMagSin] : 1, uc = k == "magnetic_field" ? scale[kMagCos] : 1;
      coef = {a * std::cos(ph) * us, a * std::sin(ph) * uc};
    }
    if (coef.size() != kc.size() + ke.size()) return std::nan("");
    VectorXd signal = VectorXd::Zero(d.n);
    for (size_t j = 0; j < kc.size(); ++j) signal += coef[j] * d.cols.col(kc[j]);
    for (size_t j = 0; j < ke.size(); ++j) signal += coef[kc.size() + j] * ke[j];
    const MatrixXd xo = WhitenRows(d, nm, Assemble(d, oc, oe));
    const VectorXd sw = WhitenRows(d, nm, signal);
    const LsFit g = SolveLs(xo, sw);
    z_min = std::min(z_min, std::sqrt(g.rss));
  }
  return z_min;
}

// The misses that are choices (the named causes differ from the hidden ones), weighed by the criterion
// itself: the hidden model's BIC against the named chain's. Where the named chain's is lower (or the
// hidden one's lower by less than kBareMentionBic) no search by this criterion names the hidden pair;
// where the hidden one's is lower by more, the search missed what its criterion supports. And every case's
// outcome by its weaker hidden cause's strength (WeakerHiddenZ): below kStrengthEdges[0], between, above
// kStrengthEdges[1].
constexpr double kStrengthEdges[2] = {5, 8};
struct MissOracle {
  int weighed = 0, named_lower = 0, hidden_lower_by_more = 0;
  int cases[3] = {0, 0, 0}, both[3] = {0, 0, 0}, wrong[3] = {0, 0, 0};
};
void WeighCase(const testing::GyroCase& c, const GyroDiscovery& res, MissOracle* mo) {
  std::set<std::string> named;
  std::map<std::string, std::map<std::string, double>> named_par;
  for (const auto& n : res.causes) named.insert(n.cause), named_par[n.cause] = n.parameters;
  const GyroDiscoverOptions o;
  Design d = BuildDesign(c.logs, o);
  std::vector<bool> usable;
  std::vector<double> scale;
  const std::vector<int> full = UsableColumns(&d, o, &usable, &scale);
  const GyroStep s0 = RunGyroStep(d, o, usable, scale, full, {}, o.alpha, o.gain_alpha, c.logs.front().file);
  const double z = WeakerHiddenZ(d, o, s0.nm, scale, c);
  if (!std::isfinite(z)) ADD_FAILURE() << "no strength for the hidden causes of a case";
  const int bin = z < kStrengthEdges[0] ? 0 : z < kStrengthEdges[1] ? 1 : 2;
  const testing::GyroMultiOutcome outcome = testing::ScoreGyroMultiOutcome(c, res);
  ++mo->cases[bin];
  mo->both[bin] += outcome.all_named;
  mo->wrong[bin] += outcome.wrong;
  std::cout << "   weaker hidden cause z " << z << "\n";
  if (named == std::set<std::string>(c.causes.begin(), c.causes.end())) return;  // `unexplained`: not a choice
  double bic_hidden = 0, bic_named = 0;
  if (!ModelBic(d, o, s0.nm, c.causes, c.truths, &bic_hidden) ||
      !ModelBic(d, o, s0.nm, std::vector<std::string>(named.begin(), named.end()), named_par, &bic_named)) {
    return;
  }
  ++mo->weighed;
  mo->named_lower += bic_named <= bic_hidden;
  mo->hidden_lower_by_more += bic_hidden + kBareMentionBic < bic_named;
  std::cout << "   hidden - named BIC " << bic_hidden - bic_named << "\n";
}

// Every pair of the six causes, four draws each from seeds seed0 + 7919 i (RunGyroMultiMonteCarlo's order);
// prints the figures, each pair's count and the misses weighed by the criterion and the
// outcomes by strength (WeighCase).
testing::GyroMultiSummary RunPairs(uint64_t seed0, MissOracle* mo) {
  const auto pairs = testing::GyroCausePairs(
      {"temperature", "temperature_gradient", "magnetic_field", "bias_step", "periodic_drift", "scale_factor"});
  testing::GyroMultiSummary s;
  int i = 0;
  for (int k = 0; k < 4; ++k) {
    for (const auto& combo : pairs) {
      const testing::GyroCase c = testing::MakeGyroCase(combo, seed0 + 7919 * i++);
      const GyroDiscovery res = DiscoverGyro(c.logs, GyroDiscoverOptions{});
      testing::ScoreGyroMulti(c, res, true, &s);
      WeighCase(c, res, mo);
    }
  }
  std::cout << "both named " << s.all_named << "/" << s.cases << ", a wrong cause " << s.wrong << ", unexplained "
            << s.unexplained << ", parameters within 3 sigma " << s.params_within_3_sigma << "/" << s.params_checked
            << "\n";
  std::cout << "rivals: a wrong cause with the hidden one as its rival " << s.wrong_hidden_rival << "/" << s.wrong
            << ", both named and a rival listed " << s.all_named_with_rival << "/" << s.all_named << "\n";
  for (const auto& [combo, rc] : s.per_combo) std::cout << "  " << combo << " " << rc.first << "/" << rc.second << "\n";
  std::cout << "misses weighed " << mo->weighed << ": the named chain's BIC lower " << mo->named_lower
            << ", the hidden model's lower by more than " << kBareMentionBic << " " << mo->hidden_lower_by_more << "\n";
  const char* range[3] = {"z < 5", "5 <= z < 8", "z >= 8"};  // kStrengthEdges
  for (int k = 0; k < 3; ++k) {
    std::cout << "weaker hidden cause " << range[k] << ": both named " << mo->both[k] << "/" << mo->cases[k]
              << ", a wrong cause " << mo->wrong[k] << "\n";
  }
  return s;
}

// Where the weaker hidden cause is at least kStrengthEdges[1] sigma strong (WeakerHiddenZ), the issue's
// figures hold on the three draws together: both named 91/100, a wrong cause 5/100 (docs/discrepancy.md;
// per draw 35/36 and 1, 24/27 and 2, 32/37 and 2). These bounds hold each draw's figures against regression.
void ExpectStrongCases(const MissOracle& mo) {
  EXPECT_GE(mo.both[2], 0.85 * mo.cases[2]);
  EXPECT_LE(mo.wrong[2], 0.1 * mo.cases[2]);
}

TEST(DiscoverGyroMultiLong, TwoCausesTogether) {
  MissOracle mo;
  const auto s = RunPairs(626262, &mo);
  // The issue asks both named >= 90 % and a wrong cause <= 5 %: measured 50/60 and 4/60, not met
  // (docs/discrepancy.md: the misses are a weak temperature gradient not significant at any step 5, ties
  // the data do not break 4 - rate_random_walk for a step or field with a temperature drift 2, misalignment
  // for a field harmonic near its phase 1, temperature for a step 1 - and an `unexplained` 1). These bounds
  // hold the measured figures against regression.
  EXPECT_GE(s.all_named, 0.8 * s.cases);
  EXPECT_LE(s.wrong, 0.1 * s.cases);
  EXPECT_GE(s.params_within_3_sigma, 0.95 * s.params_checked);
  // The search's own misses: at most 3 cases a draw where the hidden pair's BIC was more than 2 below the
  // named chain's (docs/discrepancy.md).
  EXPECT_LE(mo.hidden_lower_by_more, 3);
  ExpectStrongCases(mo);
}

// A second draw of the same 60 cases (seed base 737373): the first draw is the one the stepwise extension's
// first fixes were measured on. Measured 49/60 both named and a wrong cause 7/60 (44/60 and 12/60 before the
// walk and lag chains of RunChain, which this draw showed); docs/discrepancy.md: thermal_lag for a temperature
// with its gradient 2, misalignment for a field harmonic 2, a step refused as a trend then misalignment and
// thermal_lag 1, rate_random_walk 1, temperature for a step 1. The bounds hold these figures against regression.
TEST(DiscoverGyroMultiLong, TwoCausesFreshSeeds) {
  MissOracle mo;
  const auto s = RunPairs(737373, &mo);
  EXPECT_GE(s.all_named, 0.75 * s.cases);
  EXPECT_LE(s.wrong, 0.15 * s.cases);
  EXPECT_GE(s.params_within_3_sigma, 0.95 * s.params_checked);
  // The search's own misses: at most 3 cases a draw where the hidden pair's BIC was more than 2 below the
  // named chain's (docs/discrepancy.md).
  EXPECT_LE(mo.hidden_lower_by_more, 3);
  ExpectStrongCases(mo);
}

// A third draw (seed base 848484), not looked at while the walk and lag chains were developed: measured
// 48/60 both named, a wrong cause 7/60, parameters within 3 sigma 192/194 (docs/discrepancy.md).
TEST(DiscoverGyroMultiLong, TwoCausesThirdDraw) {
  MissOracle mo;
  const auto s = RunPairs(848484, &mo);
  EXPECT_GE(s.all_named, 0.75 * s.cases);
  EXPECT_LE(s.wrong, 0.15 * s.cases);
  EXPECT_GE(s.params_within_3_sigma, 0.95 * s.params_checked);
  // The search's own misses: at most 3 cases a draw where the hidden pair's BIC was more than 2 below the
  // named chain's (docs/discrepancy.md).
  EXPECT_LE(mo.hidden_lower_by_more, 3);
  ExpectStrongCases(mo);
}

// The step's pairs (temperature, scale_factor and magnetic_field each with bias_step; 18 draws each) on the
// generator's thermal programme and on the same programme repeated (GyroCaseModel::repeat_programme, the
// same draws otherwise). Run once, the programme crosses each temperature once and sits mostly on two
// plateaus: a step during the ramp-down is then a function of the temperature, and K10, K20 (or a lag, or
// K01) take its place. Measured (docs/discrepancy.md): a thermal term named where the step is missed 8/54
// once, 0/54 repeated; both named 31/54 and 40/54, a wrong cause 13 and 9 (in one case a third).
TEST(DiscoverGyroMultiLong, StepPairsOnARepeatedThermalProgramme) {
  const std::vector<std::vector<std::string>> pairs = {
      {"temperature", "bias_step"}, {"bias_step", "scale_factor"}, {"magnetic_field", "bias_step"}};
  int both[2] = {0, 0}, wrong[2] = {0, 0}, thermal_for_step[2] = {0, 0};
  for (int rep = 0; rep < 2; ++rep) {
    int i = 0;
    for (uint64_t seed0 : {999001, 999002, 999003}) {
      for (int k = 0; k < 6; ++k) {
        for (const auto& combo : pairs) {
          const testing::GyroCase c = testing::MakeGyroCase(combo, seed0 + 7919 * (i++ % 18), rep == 1);
          const GyroDiscovery res = DiscoverGyro(c.logs, GyroDiscoverOptions{});
          std::set<std::string> named;
          for (const auto& n : res.causes) named.insert(n.cause);
          const testing::GyroMultiOutcome outcome = testing::ScoreGyroMultiOutcome(c, res);
          both[rep] += outcome.all_named;
          wrong[rep] += outcome.wrong;
          thermal_for_step[rep] +=
              !named.count("bias_step") &&
              (named.count("temperature") || named.count("temperature_gradient") || named.count("thermal_lag"));
        }
      }
    }
    std::cout << (rep ? "repeated" : "once") << ": both named " << both[rep] << "/54, a wrong cause " << wrong[rep]
              << ", a thermal term named where the step is missed " << thermal_for_step[rep] << "\n";
  }
  EXPECT_LE(thermal_for_step[1], 1);
  EXPECT_GE(thermal_for_step[0], thermal_for_step[1] + 4);
  EXPECT_GE(both[1], both[0]);
}

}  // namespace
}  // namespace ssiu
