// `ssiu discover gyro` (method in discover_gyro.h): the stepwise extension of the model, the named
// causes' joint fit and relocation in the final model, and DiscoverGyro.
#include "discover/discover_gyro.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "calibration/allan.h"
#include "core/error.h"
#include "discover/discover_gyro_internal.h"

namespace ssiu::discover_internal {

// The rivals of the named cause `nc` among one step's candidates (GyroRival), that step's base model holding
// the other named causes: the significant candidates whose BIC (BicOrder's, exact likelihood) lies less than
// kBareMentionBic above the named one's and that no gate of the step refused; for the nested pair
// misalignment / magnetic_field, 2 ln of FieldPhaseWarranted's Bayes factor instead (the BIC counts the
// field's phase as a full parameter, which the Bayes factor weighs by the harmonic's strength).
// scale_factor and scale_factor_asymmetry are one effect with and without the sign split: no rivals.
std::vector<GyroRival> StepRivals(const NamedCause& nc, const std::vector<GyroCandidate>& candidates) {
  const GyroCandidate* named = nullptr;
  for (const auto& c : candidates) {
    if (c.cause == nc.candidate.cause && c.model == nc.candidate.model && c.applicable && c.significant) named = &c;
  }
  std::vector<GyroRival> out;
  if (!named) return out;
  for (const auto& c : candidates) {
    if (!c.applicable || !c.significant || c.cause == named->cause) continue;
    double delta = 0;
    if (NestedPair(c.cause, named->cause)) {
      const bool mis_named = named->cause == "misalignment";
      if ((!mis_named && c.cause != "misalignment") || c.model == "logged_field" || named->model == "logged_field")
        continue;
      const GyroCandidate& field = mis_named ? c : *named;
      const GyroCandidate& mis = mis_named ? *named : c;
      // 2 ln B(misalignment : field) (FieldPhaseWarranted's Laplace approximation).
      const double two_ln_b = FieldPhaseExtraChi2Even(field.statistic) - (field.statistic - mis.statistic);
      delta = mis_named ? two_ln_b : -two_ln_b;
    } else {
      // Refused by a gate of the step; not a walk or lag that the chain without it matched (RunChain).
      if (!c.verdict.empty() && c.verdict != "named" && c.verdict.rfind(kChainWithoutIt, 0) != 0) continue;
      delta = c.bic - named->bic;
    }
    if (delta < kBareMentionBic) out.push_back({c.cause, c.model, delta});
  }
  std::sort(out.begin(), out.end(), [](const GyroRival& a, const GyroRival& b) { return a.delta_bic < b.delta_bic; });
  return out;
}

namespace {

// The full model's columns that a named cause's columns (now in the base) would repeat, or, for
// misalignment (a fixed-phase harmonic of the azimuth), span.
std::vector<int> FreeColumns(const std::vector<int>& full_cols, const std::vector<NamedCause>& named) {
  std::set<int> taken;
  for (const auto& nc : named) {
    taken.insert(nc.cols.begin(), nc.cols.end());
    if (std::count(nc.cols.begin(), nc.cols.end(), kMis)) taken.insert({kMagSin, kMagCos});
  }
  std::vector<int> out;
  for (int c : full_cols) {
    if (!taken.count(c)) out.push_back(c);
  }
  return out;
}

// The base model bias + the named causes' columns, those of cause `skip` left out (-1: none).
MatrixXd BaseWithNamed(const Design& d, const MatrixXd& bias, const std::vector<NamedCause>& named, int skip) {
  std::vector<VectorXd> add;
  for (int k = 0; k < static_cast<int>(named.size()); ++k) {
    if (k == skip) continue;
    for (int c : named[k].cols) add.push_back(d.cols.col(c));
    for (const auto& v : named[k].extra) add.push_back(v);
  }
  MatrixXd x(d.n, bias.cols() + static_cast<Eigen::Index>(add.size()));
  x.leftCols(bias.cols()) = bias;
  for (size_t j = 0; j < add.size(); ++j) x.col(bias.cols() + static_cast<Eigen::Index>(j)) = add[j];
  return x;
}

// Calls fn(k) for each named cause k with the base model holding the biases and every other named cause
// (as they are when fn is called: fn may change cause k), then sets the base to the biases + all of them.
void WithOthersInBase(Design* d, const std::vector<NamedCause>& named, const std::function<void(int)>& fn) {
  const MatrixXd bias = d->base.leftCols(static_cast<Eigen::Index>(d->bins.size()));
  for (int k = 0; k < static_cast<int>(named.size()); ++k) {
    d->base = BaseWithNamed(*d, bias, named, k);
    fn(k);
  }
  d->base = BaseWithNamed(*d, bias, named, -1);
}

// Names of a named cause's coefficients in the joint fit (for the correlations).
std::vector<std::string> CoefficientNames(const NamedCause& nc) {
  static const std::map<int, std::string> kName = {{kT1, "K10_dph"},
                                                   {kT2, "K20_dph"},
                                                   {kG1, "K01_dph"},
                                                   {kMagSin, "sin_azimuth_dph"},
                                                   {kMagCos, "cos_azimuth_dph"},
                                                   {kBn, "sensitivity_bn_dph_per_ut"},
                                                   {kBe, "sensitivity_be_dph_per_ut"},
                                                   {kBh, "sensitivity_bh_dph_per_ut"},
                                                   {kMis, "misalignment_arcsec"},
                                                   {kScale, "scale_factor_ppm"},
                                                   {kAbsRef, "abs_ref_ppm"},
                                                   {kDelay, "delay_s"},
                                                   {kLag, "K_lag_dph"}};
  std::vector<std::string> out;
  for (int c : nc.cols) out.push_back(nc.candidate.cause + "." + kName.at(c));
  if (nc.candidate.cause == "bias_step") out.push_back("bias_step.step_dph");
  if (nc.candidate.cause == "periodic_drift")
    out.push_back("periodic_drift.sin_dph"), out.push_back("periodic_drift.cos_dph");
  return out;
}

// The joint fit of the final model (one GLS of the biases + every named cause under the noise models nm):
// each cause's parameters and sigmas as EvaluateFitted reports them for that cause with the others in the
// base model (the same fit, its columns in another order), and the correlations of the coefficients of
// different causes with |r| > kReportedCorrelation.
constexpr double kReportedCorrelation = 0.3;
void JointFit(Design* design, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm,
              const std::vector<double>& scale, const std::vector<NamedCause>& named, GyroDiscovery* res) {
  const Design& d = *design;
  const int l = static_cast<int>(d.bins.size());
  const VectorXd yw = WhitenRows(d, nm, d.y);
  const MatrixXd xw = WhitenRows(d, nm, d.base);
  const LsFit joint = SolveLs(xw, yw);
  const double infl = VarianceInflation(d, yw - xw * joint.beta, o.max_noise_lag);
  WithOthersInBase(design, named, [&](int k) {
    const NamedCause& nc = named[k];
    GyroNamedCause gc;
    gc.cause = nc.candidate.cause;
    gc.model = nc.candidate.model;
    gc.gain = nc.candidate.gain;
    gc.gain_z = nc.candidate.gain_z;
    gc.rms_before_dph = nc.ev.cv.rms_before;
    gc.rms_after_dph = nc.ev.cv.rms_after;
    gc.parameters = nc.ev.parameters, gc.sigmas = nc.ev.sigmas;  // a walk: its step's (it is in the noise model)
    if (gc.cause != "rate_random_walk" && named.size() > 1) {
      Fitted fit;
      fit.cols = nc.cols;
      fit.x = Assemble(d, nc.cols, nc.extra);
      fit.gls = SolveLs(WhitenRows(d, nm, fit.x), yw);
      fit.inflation = infl;
      Evaluation ev;
      EvaluateFitted(d, o, nm, fit, gc.cause, scale, nc.step_scan, nc.periodic_scan, &ev);
      gc.parameters = ev.parameters, gc.sigmas = ev.sigmas;
    }
    gc.parameters.erase("swing_ratio");  // gate quantities, not parameters of the cause
    gc.parameters.erase("lag_vs_none_chi2");
    res->causes.push_back(gc);
  });
  // Correlations of the coefficients (columns l.. of the joint fit, in the order the causes entered).
  std::vector<std::string> names;
  std::vector<int> owner;
  for (int k = 0; k < static_cast<int>(named.size()); ++k) {
    for (const auto& nm_k : CoefficientNames(named[k])) names.push_back(nm_k), owner.push_back(k);
  }
  const MatrixXd& cov = joint.cov_unscaled;
  for (size_t i = 0; i < names.size(); ++i) {
    for (size_t j = i + 1; j < names.size(); ++j) {
      if (owner[i] == owner[j]) continue;
      const int a = l + static_cast<int>(i), b = l + static_cast<int>(j);
      const double r = cov(a, b) / std::sqrt(cov(a, a) * cov(b, b));
      if (std::abs(r) > kReportedCorrelation) res->correlations.push_back({names[i], names[j], r});
    }
  }
}

// The located causes of the chain (bias_step's step, periodic_drift's sinusoid) located again in the final
// model, the other named causes in the base: a sinusoid located before a field harmonic was fitted took
// part of the azimuth staircase (its 4th harmonic of 6 h lies at 1.5 h, within the orbital periods) and
// left the folded-shape test a structure (p 0.001). The scans of one step, on the base model's GLS
// residual under nm, the statistic scaled by that residual's variance and inflation.
void RelocateNamed(Design* design, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm,
                   std::vector<NamedCause>* named) {
  const Design& d = *design;
  const VectorXd yw = WhitenRows(d, nm, d.y);
  WithOthersInBase(design, *named, [&](int k) {
    NamedCause& nc = (*named)[k];
    const bool step = nc.candidate.cause == "bias_step", periodic = nc.candidate.cause == "periodic_drift";
    if (!step && !periodic) return;
    const MatrixXd bw = WhitenRows(d, nm, d.base);
    const LsFit g = SolveLs(bw, yw);
    const VectorXd res = yw - bw * g.beta;
    const double sigma2_f =
        g.rss / std::max(1, d.n - static_cast<int>(bw.cols())) * VarianceInflation(d, res, o.max_noise_lag);
    if (step) {
      StepScan sc;
      ScanStep(d, nm, bw, res, sigma2_f, &sc);
      if (sc.best_step.size() == d.n) nc.step_scan = sc, nc.extra = {sc.best_step};
    } else {
      PeriodicScan sc;
      ScanPeriodic(d, nm, bw, res, o, 1, sigma2_f, &sc);
      if (sc.best_sin.size() == d.n) nc.periodic_scan = sc, nc.extra = {sc.best_sin, sc.best_cos};
    }
  });
}

// A nested cause named in the chain (misalignment, scale_factor) is tested again against its wider partner
// (magnetic_field's azimuth harmonic, scale_factor_asymmetry) in the final model, the other named causes in
// the base: the partner's extra terms are weighed as Upgrade weighs them at a step, now with every other cause fitted
// too (at its step the wider one's phase was 3-8 chi^2 from significance when a temperature gradient or a scale factor
// was still unfitted). A cause widened so keeps its step's gain; its parameters are the joint fit's.
void WidenNested(Design* design, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm,
                 const std::vector<bool>& usable, std::vector<NamedCause>* named) {
  const Design& d = *design;
  const VectorXd yw = WhitenRows(d, nm, d.y);
  WithOthersInBase(design, *named, [&](int k) {
    NamedCause& nc = (*named)[k];
    std::vector<int> wide;
    std::string cause, model;
    if (nc.candidate.cause == "misalignment")
      wide = {kMagSin, kMagCos}, cause = "magnetic_field", model = "azimuth_harmonic";
    if (nc.candidate.cause == "scale_factor") wide = {kScale, kAbsRef}, cause = "scale_factor_asymmetry";
    if (wide.empty() || !usable[wide[0]] || !usable[wide[1]]) return;
    const MatrixXd xn = WhitenRows(d, nm, Assemble(d, nc.cols, {})), xw = WhitenRows(d, nm, Assemble(d, wide, {}));
    const LsFit gn = SolveLs(xn, yw), gw = SolveLs(xw, yw);
    const double s2 = gw.rss / std::max(1, d.n - static_cast<int>(xw.cols()));
    const double infl = VarianceInflation(d, yw - xw * gw.beta, o.max_noise_lag);
    const double stat = std::max(0.0, (gn.rss - gw.rss) / (s2 * infl));
    // The wider one's chi^2 against the model without either: only the field's choice uses it.
    const double wide_chi2 = cause == "magnetic_field"
                                 ? std::max(0.0, (SolveLs(WhitenRows(d, nm, d.base), yw).rss - gw.rss) / (s2 * infl))
                                 : 0.0;
    if (WiderWarranted(nc.candidate.cause, stat, wide_chi2, static_cast<int>(wide.size() - nc.cols.size()), o.alpha)) {
      nc.candidate.cause = cause, nc.candidate.model = model, nc.cols = wide;
    }
  });
}

// thermal_lag named in a chain is weighed again with the other named causes in the model: a lag found at
// a step where another cause was still unmodelled (a field harmonic's staircase smoothed by the lag) must
// still beat the temperature itself (K10, both with K20) by the likelihood ratio, else it is `temperature`.
void NarrowLag(Design* design, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm,
               std::vector<NamedCause>* named) {
  const Design& d = *design;
  const VectorXd yw = WhitenRows(d, nm, d.y);
  WithOthersInBase(design, *named, [&](int k) {
    NamedCause& nc = (*named)[k];
    if (nc.candidate.cause != "thermal_lag") return;
    const MatrixXd xl = WhitenRows(d, nm, Assemble(d, {kLag, kT2}, {}));
    const MatrixXd xt = WhitenRows(d, nm, Assemble(d, {kT1, kT2}, {}));
    const LsFit gl = SolveLs(xl, yw), gt = SolveLs(xt, yw);
    const double s2 = gl.rss / std::max(1, d.n - static_cast<int>(xl.cols()));
    const double infl = VarianceInflation(d, yw - xl * gl.beta, o.max_noise_lag);
    if (!((gt.rss - gl.rss) / (s2 * infl) > kLagMinTauZ * kLagMinTauZ)) {
      nc.candidate.cause = "temperature", nc.cols = {kT1, kT2};
    }
  });
}

// Stepwise extension (issue 31): step s tests every cause not yet named against the base model extended by
// the causes named before (their columns in d.base: one GLS of the biases and all of them), names the best
// as one step always did, and the next step starts from the extended model; it stops when no candidate
// passes, after rate_random_walk (a change of the noise model, not a column), or after kMaxSteps.
// False alarms across steps: step s tests at alpha 2^-s (candidates) and gain_alpha 2^-s (held-out gate).
// A step only runs after the one before named a cause, so on clean logs the family-wise false-alarm
// probability is step 0's, alpha, as before; with k true causes in the data, any wrongly named cause
// costs at most sum_s alpha 2^-s < 2 alpha (union bound over the steps), and a further cause after the
// true ones at most alpha 2^(1-k).
constexpr int kMaxSteps = 6;

// What a named cause keeps out of the later steps' candidates.
void ExcludeWithNamed(const std::string& cause, std::set<std::string>* excluded) {
  excluded->insert(cause);
  // Nested pairs share columns: neither joins a model that holds the other.
  if (cause == "magnetic_field" || cause == "misalignment") excluded->insert({"magnetic_field", "misalignment"});
  if (cause == "scale_factor" || cause == "scale_factor_asymmetry") {
    excluded->insert({"scale_factor", "scale_factor_asymmetry"});
  }
  // The temperature causes are one effect seen three ways (eq. (1) and its lag, docs/discrepancy.md).
  if (cause == "temperature" || cause == "temperature_gradient" || cause == "thermal_lag") {
    excluded->insert("thermal_lag");
    if (cause == "thermal_lag") excluded->insert({"temperature", "temperature_gradient"});
  }
}

// The chain's state: the causes named so far (their columns in d.base), what the later steps leave out,
// and each step run (its candidates and noise figures; the named cause moved into `named`).
struct Chain {
  Design d;
  std::vector<NamedCause> named;
  std::set<std::string> excluded;
  std::vector<GyroStep> steps;
};

// The BIC of the exact likelihood of the chain's deterministic model against its model before cause
// `from` entered (FittedBic: the causes from `from` on are the terms counted), under noise models nm.
double ChainBic(const Chain& c, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm, size_t from) {
  int dof = 0;
  double cost = 0;
  for (size_t k = from; k < c.named.size(); ++k) dof += c.named[k].candidate.dof, cost += c.named[k].position_cost;
  return FittedBic(c.d, o, nm, c.d.base, dof, cost);
}

// The chain's deterministic model with its located terms placed again with the others fitted
// (RelocateNamed, as the final model has them), its BIC against the model before cause `from` (ChainBic).
double FinalChainBic(Chain c, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm, size_t from) {
  if (c.named.size() > 1) RelocateNamed(&c.d, o, c.named.back().nm, &c.named);
  return ChainBic(c, o, nm, from);
}

// Runs the steps from c->steps.size() on until no candidate passes (module comment: alpha 2^-s at step s).
// Two causes describe several others: a random walk of the bias every slow structure (it ends the chain),
// a first-order lag of the temperature eq. (1)'s K10 with K01 = -tau K10 (one coefficient and a located
// time constant against three). A step that names either is a choice between two descriptions that the
// greedy order makes from one step's evidence: the chain is run again from that step without it, and the
// chain whose deterministic model has the lower BIC of the exact likelihood is kept (Schwarz 1978: the
// larger approximate posterior probability; the walk's BIC counts the same noise parameters as
// FittedBic). When the two BICs lie within kBareMentionBic the data do not choose, and the chain without
// the walk or the lag is kept: eq. (1)'s terms and the vocabulary's deterministic causes are the model of
// the seed paper, the lag and the walk the ones that can stand for others. Without this, on a draw the
// procedure was not tuned on, a gradient with a periodic drift and a temperature with a step were named
// thermal_lag (BIC 0.7 and 0.9 above the chain without it).
void RunChain(const GyroDiscoverOptions& o, const std::vector<bool>& usable, const std::vector<double>& scale,
              const std::vector<int>& full_cols, const std::string& first_file, Chain* c) {
  for (int step = static_cast<int>(c->steps.size()); step < kMaxSteps; ++step) {
    const double share = std::ldexp(1.0, -step);
    GyroStep s = RunGyroStep(c->d, o, usable, scale, FreeColumns(full_cols, c->named), c->excluded, o.alpha * share,
                             o.gain_alpha * share, first_file);
    const std::string cause = s.named ? s.cause.candidate.cause : "";
    if (cause == "rate_random_walk" || cause == "thermal_lag") {
      const size_t before = c->named.size();
      const std::vector<NoiseModel> nm = s.nm;
      GyroCandidate chosen = s.cause.candidate;
      Chain trial = *c;
      trial.excluded.insert(cause);
      RunChain(o, usable, scale, full_cols, first_file, &trial);
      c->named.push_back(std::move(s.cause));
      c->steps.push_back(std::move(s));
      ExcludeWithNamed(cause, &c->excluded);
      double bic = chosen.bic;  // the walk: in the noise model, it ends the chain
      if (cause == "thermal_lag") {
        c->d.base = BaseWithNamed(c->d, c->d.base, {c->named.back()}, -1);
        RunChain(o, usable, scale, full_cols, first_file, c);
        bic = FinalChainBic(*c, o, nm, before);
      }
      if (trial.named.size() > before && FinalChainBic(trial, o, nm, before) < bic + kBareMentionBic) {
        chosen.verdict = kChainWithoutIt;
        trial.steps[step].candidates.push_back(chosen);
        *c = std::move(trial);
      }
      return;
    }
    const bool named = s.named;
    if (named) c->named.push_back(std::move(s.cause));
    c->steps.push_back(std::move(s));
    if (!named) break;
    ExcludeWithNamed(cause, &c->excluded);
    c->d.base = BaseWithNamed(c->d, c->d.base, {c->named.back()}, -1);
  }
}

// Each named cause's rivals (StepRivals) in the final model: its candidates against the biases and every other
// named cause. The last named one's are those of the step that named it (its base held the others); each
// earlier one's come from a step run again with the causes named after it in the base too.
void FindRivals(const Chain& c, const GyroDiscoverOptions& o, const std::vector<bool>& usable,
                const std::vector<double>& scale, const std::vector<int>& full_cols, const std::string& first_file,
                GyroDiscovery* res) {
  const int n_named = static_cast<int>(c.named.size());
  const MatrixXd bias = c.d.base.leftCols(static_cast<Eigen::Index>(c.d.bins.size()));
  for (int k = 0; k < n_named && k < static_cast<int>(res->causes.size()); ++k) {
    if (k == n_named - 1) {
      res->causes[k].rivals = StepRivals(c.named[k], c.steps[k].candidates);
      continue;
    }
    Design d = c.d;
    d.base = BaseWithNamed(c.d, bias, c.named, k);
    std::vector<NamedCause> others;
    std::set<std::string> excluded;
    for (int j = 0; j < n_named; ++j) {
      if (j != k) others.push_back(c.named[j]), ExcludeWithNamed(c.named[j].candidate.cause, &excluded);
    }
    const GyroStep s =
        RunGyroStep(d, o, usable, scale, FreeColumns(full_cols, others), excluded, o.alpha, o.gain_alpha, first_file);
    res->causes[k].rivals = StepRivals(c.named[k], s.candidates);
  }
}

}  // namespace

}  // namespace ssiu::discover_internal

namespace ssiu {

using namespace discover_internal;

GyroDiscovery DiscoverGyro(const std::vector<GyroBenchLog>& logs, const GyroDiscoverOptions& o) {
  o.Check();
  if (logs.empty()) throw InputError("", "no gyro log given");
  Chain chain;
  chain.d = BuildDesign(logs, o);
  std::vector<bool> usable;
  std::vector<double> scale;
  const std::vector<int> full_cols = UsableColumns(&chain.d, o, &usable, &scale);
  RunChain(o, usable, scale, full_cols, logs.front().file, &chain);
  Design& d = chain.d;
  std::vector<NamedCause>& named = chain.named;
  GyroDiscovery res;
  res.n_bins = d.n;
  const GyroStep& s0 = chain.steps.front();
  res.candidates = s0.candidates;
  res.alpha_per_candidate = s0.alpha_each;
  res.gain_z_min = s0.z_min;
  res.variance_inflation = s0.inflation;
  res.n_eff = d.n / s0.inflation;
  ReportLongestLogNoise(d, s0.nm, &res);
  const std::vector<NoiseModel>& nm0 = s0.nm;
  const int periodic_log0 = s0.periodic_log;
  for (size_t k = 1; k < chain.steps.size(); ++k) res.later_steps.push_back(chain.steps[k].candidates);

  if (named.size() > 1) {
    RelocateNamed(&d, o, named.back().nm, &named);
    WidenNested(&d, o, named.back().nm, usable, &named);
    NarrowLag(&d, o, named.back().nm, &named);
  }
  // 6. The final model's residual (one GLS of the biases + every named cause, under the noise models of
  // the step that named the last one; the walk's when that was rate_random_walk) against its noise model.
  const std::vector<NoiseModel>& nm_fit = named.empty() ? nm0 : named.back().nm;
  const LsFit joint = SolveLs(WhitenRows(d, nm_fit, d.base), WhitenRows(d, nm_fit, d.y));
  const VectorXd e_fit = d.y - d.base * joint.beta;
  std::vector<NoiseModel> noise_fit = nm_fit;
  if (!named.empty() && named.back().candidate.cause == "rate_random_walk") {
    noise_fit = named.back().nm_walk;  // the walk is in the noise model: its innovations are the residual
  } else {
    // The noise model of this model's residual: the full model's one was fitted without the terms of
    // every candidate (and the best noise sinusoid), so it misses part of the wander left here.
    RefitResidualNoise(d, o, e_fit, &noise_fit);
  }
  if (named.empty()) {
    res.cause = "none";
    const CvResult cv = CrossValidate(d, nm0, d.base, o.cv_blocks);
    res.rms_before_dph = res.rms_after_dph = cv.rms_before;
    res.gain = 1;
  } else {
    JointFit(&d, o, nm_fit, scale, named, &res);
    FindRivals(chain, o, usable, scale, full_cols, logs.front().file, &res);
    const NamedCause& first = named.front();
    res.cause = first.candidate.cause;
    res.parameters = res.causes.front().parameters;  // its step's fit alone; the joint fit's with others
    res.sigmas = res.causes.front().sigmas;
    res.rms_before_dph = first.ev.cv.rms_before;
    res.rms_after_dph = first.ev.cv.rms_after;
    res.gain = first.candidate.gain;
    res.gain_z = first.candidate.gain_z;
  }
  double fundamental_hz = 0;
  int fundamental_log = periodic_log0;
  for (const auto& nc : named) {
    if (nc.candidate.cause == "periodic_drift") {
      fundamental_hz = nc.periodic_scan.best_freq, fundamental_log = nc.periodic_scan.best_periodic_log;
    }
  }
  res.residual = TestResidual(d, noise_fit, e_fit, o, fundamental_hz, fundamental_log);
  if (res.residual.structured) {
    res.partial_cause = res.cause == "none" ? "" : res.cause;
    res.cause = "unexplained";
  }
  return res;
}

}  // namespace ssiu
