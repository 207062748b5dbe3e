#include "discover/discover_allan.h"

#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/distributions/normal.hpp>
#include <cmath>

#include "core/error.h"

namespace ssiu {

void AllanDiscrepancyOptions::Check() const {
  if (!(sigmas > 0)) throw InputError("options", "sigmas must be > 0");
  if (!(alpha > 0 && alpha < 1)) throw InputError("options", "alpha must be in (0, 1)");
  if (!(gain_alpha > 0 && gain_alpha < 1)) throw InputError("options", "gain_alpha must be in (0, 1)");
}

namespace {

// The terms of the IEEE 952 model avar(tau) = 3Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2
// (Annex C, as allan.h's FitNoiseTerms), linear in the squared coefficients.
enum Term { kQ, kN, kB, kK, kR, kTerms };
const char* const kTermName[kTerms] = {"quantization", "arw", "bias_instability", "rate_random_walk", "rate_ramp"};

double TermShape(int t, double tau) {
  switch (t) {
    case kQ:
      return 3 / (tau * tau);
    case kN:
      return 1 / tau;
    case kB:
      return 2 * std::log(2.0) / M_PI;
    case kK:
      return tau / 3;
    default:
      return tau * tau / 2;
  }
}

// The curve as weighted least squares in avar: row i of a holds w_i TermShape(t, tau_i), y_i = w_i adev_i^2,
// with w_i = sqrt(share_i) / sigma_avar_i (sigma from the point's edf and the 2 % model-error floor of
// FitNoiseTerms; share: the point's share of an octave, overlapping points being correlated).
struct WeightedCurve {
  Eigen::MatrixXd a;
  Eigen::VectorXd y;
  std::vector<double> sig;  // 1-sigma of each ADEV point
};

WeightedCurve MakeWeightedCurve(const AllanCurve& curve) {
  const size_t n = curve.tau_s.size();
  const NoiseFitOptions nfo;
  WeightedCurve wc;
  wc.sig.resize(n);
  wc.a.resize(n, kTerms);
  wc.y.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const double rel = curve.edf.size() == n && curve.edf[i] > 0 ? std::sqrt(2 / curve.edf[i]) / 2 : 0.05;
    wc.sig[i] = curve.adev[i] * std::hypot(rel, nfo.model_error);
    const double s_avar = 2 * curve.adev[i] * wc.sig[i];
    double share = 1;
    if (n > 1) {
      const double lo =
          i > 0 ? std::log2(curve.tau_s[i] / curve.tau_s[i - 1]) : std::log2(curve.tau_s[1] / curve.tau_s[0]);
      const double hi = i + 1 < n ? std::log2(curve.tau_s[i + 1] / curve.tau_s[i]) : lo;
      share = std::min(1.0, 0.5 * (lo + hi));
    }
    const double w = std::sqrt(share) / s_avar;
    for (int t = 0; t < kTerms; ++t) wc.a(i, t) = w * TermShape(t, curve.tau_s[i]);
    wc.y(i) = w * curve.adev[i] * curve.adev[i];
  }
  return wc;
}

// A fit of some terms on some rows: the squared coefficients (0 for a term left out or dropped), their
// covariance (scaled by the fit's chi^2 per dof when above 1), chi^2 and dof.
struct TermFit {
  Eigen::VectorXd coef = Eigen::VectorXd::Zero(kTerms);
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(kTerms, kTerms);
  double chi2 = 0;
  int dof = 0;
  bool ok = false;
};

// Non-negative least squares by elimination: the most negative coefficient other than `keep` is dropped and
// the rest refitted until all are >= 0; not ok when `keep`'s own coefficient is not positive.
TermFit FitTerms(const WeightedCurve& wc, std::vector<int> terms, const std::vector<int>& rows, int keep) {
  TermFit f;
  while (!terms.empty()) {
    Eigen::MatrixXd a(rows.size(), terms.size());
    Eigen::VectorXd y(rows.size());
    for (size_t i = 0; i < rows.size(); ++i) {
      for (size_t j = 0; j < terms.size(); ++j) a(i, j) = wc.a(rows[i], terms[j]);
      y(i) = wc.y(rows[i]);
    }
    const Eigen::VectorXd b = a.colPivHouseholderQr().solve(y);
    int worst = -1;
    for (size_t j = 0; j < terms.size(); ++j) {
      if (b(j) < 0 && terms[j] != keep && (worst < 0 || b(j) < b(worst))) worst = static_cast<int>(j);
    }
    if (worst >= 0) {
      terms.erase(terms.begin() + worst);
      continue;
    }
    f.coef.setZero();
    f.dof = static_cast<int>(rows.size() - terms.size());
    f.chi2 = (y - a * b).squaredNorm();
    const Eigen::MatrixXd c = (a.transpose() * a).inverse() * std::max(1.0, f.chi2 / std::max(1, f.dof));
    for (size_t j = 0; j < terms.size(); ++j) {
      f.coef(terms[j]) = b(j);
      for (size_t k = 0; k < terms.size(); ++k) f.cov(terms[j], terms[k]) = c(j, k);
    }
    f.ok = keep < 0 || f.coef(keep) > 0;
    return f;
  }
  return f;
}

// Held-out gain of adding term `cand` to `terms`: fitted on the even points, scored on the odd ones and
// vice versa; gain = RMS of the held-out normalised residuals before / after. Its significance as in
// discover gyro's cross-validation: with e the held-out residual before and p the held-out change of the
// prediction, the improvement is 2 e.p - p.p, and z = e.p / (s |p|) is N(0, 1) when the term has no effect
// and the points' errors are s times their 1-sigma (s^2: the larger model's chi^2 per dof when above 1).
std::pair<double, double> HeldOutGain(const WeightedCurve& wc, const std::vector<int>& terms, int cand, double s2) {
  const int n = static_cast<int>(wc.y.size());
  std::vector<int> with = terms;
  with.push_back(cand);
  double ss_before = 0, ss_after = 0, ep = 0, pp = 0;
  for (int fold = 0; fold < 2; ++fold) {
    std::vector<int> train, test;
    for (int i = 0; i < n; ++i) (i % 2 == fold ? train : test).push_back(i);
    const TermFit fb = FitTerms(wc, terms, train, -1), fa = FitTerms(wc, with, train, -1);
    for (int i : test) {
      const double rb = wc.y(i) - wc.a.row(i).dot(fb.coef), ra = wc.y(i) - wc.a.row(i).dot(fa.coef);
      ss_before += rb * rb, ss_after += ra * ra;
      ep += rb * (rb - ra), pp += (rb - ra) * (rb - ra);
    }
  }
  return {ss_after > 0 ? std::sqrt(ss_before / ss_after) : 1.0, pp > 0 ? ep / std::sqrt(pp * std::max(1.0, s2)) : 0.0};
}

// The model's ADEV at tau from its squared coefficients coef.
double ModelAdev(const Eigen::VectorXd& coef, double tau) {
  double avar = 0;
  for (int t = 0; t < kTerms; ++t) avar += coef(t) * TermShape(t, tau);
  return std::sqrt(std::max(avar, 0.0));
}

// RMS of the relative departure of the model (squared coefficients coef) from the measured ADEV, in percent,
// each point weighted by its precision (adev / sigma)^2 as the fit weighs it; with the points' own relative
// 1-sigmas in place of the departures the same mean gives the level a complete model reaches.
double RelativeRmsPct(const AllanCurve& curve, const std::vector<double>& sig, const Eigen::VectorXd& coef) {
  double ss = 0, sw = 0;
  for (size_t i = 0; i < curve.tau_s.size(); ++i) {
    const double rel = ModelAdev(coef, curve.tau_s[i]) / curve.adev[i] - 1, w = std::pow(curve.adev[i] / sig[i], 2);
    ss += w * rel * rel, sw += w;
  }
  return 100 * std::sqrt(ss / sw);
}

// The tau ranges where the model adev m leaves the curve by more than `sigmas` of a point's 1-sigma; adds
// each point's squared z to *chi2.
std::vector<std::pair<double, double>> Departures(const AllanCurve& curve, const std::vector<double>& m,
                                                  const std::vector<double>& sig, double sigmas, double* chi2) {
  std::vector<std::pair<double, double>> out;
  bool in = false;
  for (size_t i = 0; i < m.size(); ++i) {
    const double z = (m[i] - curve.adev[i]) / sig[i];
    *chi2 += z * z;
    const bool dep = std::abs(z) > sigmas;
    if (dep && !in) out.push_back({curve.tau_s[i], curve.tau_s[i]});
    if (dep) out.back().second = curve.tau_s[i];
    in = dep;
  }
  return out;
}

// Stepwise extension of ARW + B (issue 31). Step s tests each term not yet in the model: its chi^2 drop
// (scaled by the larger model's chi^2 per dof when above 1, a misfit not read as evidence), chi^2_1, at
// alpha 2^-s / (terms tested), the term's coefficient positive, and its held-out gain > 1 with z above the
// one-sided quantile of gain_alpha 2^-s; of those the largest held-out gain enters. A step runs only after
// the one before named a term: on a curve the default model fits, a term is named with probability <= alpha;
// over all steps <= sum alpha 2^-s < 2 alpha.
void ExtendStepwise(const AllanCurve& curve, const AllanDiscrepancyOptions& options, AllanDiscrepancy* r) {
  const WeightedCurve wc = MakeWeightedCurve(curve);
  const int n = static_cast<int>(curve.tau_s.size());
  std::vector<int> all(n);
  for (int i = 0; i < n; ++i) all[i] = i;
  std::vector<int> model = {kN, kB}, left = {kQ, kK, kR};
  TermFit current = FitTerms(wc, model, all, -1);
  r->residual_rms_pct_before = RelativeRmsPct(curve, wc.sig, current.coef);
  double sw = 0;  // sum of the weights (adev / sigma)^2: the weighted mean of (sigma / adev)^2 is n / sw
  for (int i = 0; i < n; ++i) sw += std::pow(curve.adev[i] / wc.sig[i], 2);
  r->point_sigma_rms_pct = 100 * std::sqrt(n / sw);
  for (int step = 0; !left.empty(); ++step) {
    const double share = std::ldexp(1.0, -step);
    const double z_min =
        boost::math::quantile(boost::math::complement(boost::math::normal(), options.gain_alpha * share));
    AllanStepTerm best;
    TermFit best_fit;
    int best_term = -1;
    for (int t : left) {
      std::vector<int> with = model;
      with.push_back(t);
      const TermFit f = FitTerms(wc, with, all, t);
      if (!f.ok || f.dof < 1) continue;
      const double drop = std::max(0.0, current.chi2 - f.chi2) / std::max(1.0, f.chi2 / f.dof);
      const double p = ChiSquaredSurvival(drop, 1);
      if (!(p < options.alpha * share / static_cast<double>(left.size()))) continue;
      const auto [gain, z] = HeldOutGain(wc, model, t, f.chi2 / f.dof);
      if (!(gain > 1 && z > z_min) || (best_term >= 0 && gain <= best.gain)) continue;
      best.term = kTermName[t], best.p_value = p, best.gain = gain, best.gain_z = z;
      best.chi2_per_dof = f.chi2 / f.dof;
      best.residual_rms_pct = RelativeRmsPct(curve, wc.sig, f.coef);
      best_fit = f, best_term = t;
    }
    if (best_term < 0) break;
    model.push_back(best_term);
    left.erase(std::find(left.begin(), left.end(), best_term));
    current = best_fit;
    r->steps.push_back(best);
  }
  // The final joint fit: each coefficient c = X^2 with sigma(X) = sigma(c) / (2 X) (first order).
  NoiseTerm* terms[kTerms] = {&r->joint.quantization, &r->joint.arw, &r->joint.bias_instability, &r->joint.rrw,
                              &r->joint.rate_ramp};
  for (int t = 0; t < kTerms; ++t) {
    const double c = current.coef(t);
    terms[t]->value = c > 0 ? std::sqrt(c) : 0.0;
    terms[t]->sigma = c > 0 ? std::sqrt(current.cov(t, t)) / (2 * std::sqrt(c)) : 0.0;
  }
  for (auto& st : r->steps) {
    for (int t = 0; t < kTerms; ++t) {
      if (st.term == kTermName[t]) st.value = terms[t]->value, st.sigma = terms[t]->sigma;
    }
  }
  r->residual_rms_pct_after = RelativeRmsPct(curve, wc.sig, current.coef);
  r->joint.chi2_per_dof = current.chi2 / std::max(1, current.dof);
  r->joint.points_used = static_cast<size_t>(n);
  for (double tau : curve.tau_s) r->final_adev.push_back(ModelAdev(current.coef, tau));
  r->joint.model_adev = r->final_adev;
  // Correlations of the squared coefficients, a named term in each pair.
  for (int a = 0; a < kTerms; ++a) {
    for (int b = a + 1; b < kTerms; ++b) {
      const bool named = (a != kN && a != kB) || (b != kN && b != kB);
      const double den = std::sqrt(current.cov(a, a) * current.cov(b, b));
      if (!named || !(den > 0)) continue;
      const double rr = current.cov(a, b) / den;
      if (std::abs(rr) > 0.3) r->correlations.push_back({kTermName[a], kTermName[b], rr});
    }
  }
  double chi2 = 0;
  r->final_departures_s = Departures(curve, r->final_adev, wc.sig, options.sigmas, &chi2);
  r->left = r->final_departures_s.empty() ? "none" : "unexplained";
}

}  // namespace

AllanDiscrepancy CompareAllanToDefaultModel(const AllanCurve& curve, const AllanDiscrepancyOptions& options) {
  options.Check();
  const size_t n = curve.tau_s.size();
  if (n < 4) throw InputError("", "Allan curve has fewer than 4 points");
  AllanDiscrepancy r;
  // 1-sigma of each ADEV point: from its edf (sigma_avar / avar = sqrt(2 / edf)), with the same
  // 2 % model-error floor as FitNoiseTerms. Base: avar = N^2 / tau + c B^2, linear in (N^2, B^2); weights
  // 1 / sigma_avar^2, with each point counted for its share of an octave as in allan.h (overlapping points
  // are correlated).
  const WeightedCurve wc = MakeWeightedCurve(curve);
  const std::vector<double>& sig = wc.sig;
  const double c = TermShape(kB, 1);
  Eigen::MatrixXd a(n, 2);
  a << wc.a.col(kN), wc.a.col(kB);
  const Eigen::VectorXd& y = wc.y;
  Eigen::Vector2d p = a.colPivHouseholderQr().solve(y);
  // Non-negativity: drop a negative term and refit the other.
  if (p(0) < 0 || p(1) < 0) {
    const int keep = p(0) < 0 ? 1 : 0;
    p.setZero();
    p(keep) = std::max(0.0, a.col(keep).dot(y) / a.col(keep).squaredNorm());
  }
  r.base_arw = std::sqrt(p(0));
  r.base_bias_instability = std::sqrt(p(1));
  double chi2 = 0;
  for (size_t i = 0; i < n; ++i) r.base_adev.push_back(std::sqrt(p(0) / curve.tau_s[i] + c * p(1)));
  r.departures_s = Departures(curve, r.base_adev, sig, options.sigmas, &chi2);
  r.chi2_per_dof_before = chi2 / std::max<size_t>(1, n - 2);
  r.extended = FitNoiseTerms(curve, NoiseFitOptions{});
  double chi2e = 0;
  for (size_t i = 0; i < n && i < r.extended.model_adev.size(); ++i) {
    const double z = (r.extended.model_adev[i] - curve.adev[i]) / sig[i];
    chi2e += z * z;
  }
  int terms = 0;
  for (const NoiseTerm* t : {&r.extended.quantization, &r.extended.arw, &r.extended.bias_instability, &r.extended.rrw,
                             &r.extended.rate_ramp}) {
    terms += t->value > 0;
  }
  r.chi2_per_dof_after = chi2e / std::max<int>(1, static_cast<int>(n) - terms);
  if (r.extended.quantization.significant) r.missing_terms.push_back("quantization");
  if (r.extended.rrw.significant) r.missing_terms.push_back("rate_random_walk");
  if (r.extended.rate_ramp.significant) r.missing_terms.push_back("rate_ramp");
  ExtendStepwise(curve, options, &r);
  return r;
}

}  // namespace ssiu
