#include "calibration/allan.h"

#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/special_functions/gamma.hpp>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/error.h"

namespace ssiu {
namespace {

constexpr double kFlickerFactor = 2.0 * 0.69314718055994531 / 3.14159265358979324;  // 2 ln2 / pi

}  // namespace

const char* AllanNoiseName(AllanNoise noise) {
  switch (noise) {
    case AllanNoise::kQuantization:
      return "quantization";
    case AllanNoise::kWhiteRate:
      return "white_rate";
    case AllanNoise::kFlickerRate:
      return "flicker_rate";
    case AllanNoise::kRandomWalkRate:
      return "random_walk_rate";
  }
  return "unknown";
}

void AllanOptions::Check() const {
  if (points_per_decade < 1 || points_per_decade > 1000) {
    throw InputError("AllanOptions.points_per_decade must be in 1..1000");
  }
  if (!(confidence > 0 && confidence < 1)) throw InputError("AllanOptions.confidence must be in (0, 1)");
  if (min_samples < 4) throw InputError("AllanOptions.min_samples must be at least 4");
}

void NoiseFitOptions::Check() const {
  if (!(tau_min_s >= 0) || !(tau_max_s >= 0)) throw InputError("NoiseFitOptions: tau limits must be >= 0");
  if (tau_max_s > 0 && tau_max_s <= tau_min_s) throw InputError("NoiseFitOptions: tau_max_s <= tau_min_s");
  if (!(dominance > 0 && dominance <= 1)) throw InputError("NoiseFitOptions.dominance must be in (0, 1]");
  if (iterations < 1 || iterations > 100) throw InputError("NoiseFitOptions.iterations must be in 1..100");
  if (!(model_error >= 0 && model_error < 1)) throw InputError("NoiseFitOptions.model_error must be in [0, 1)");
  if (!(floor_min_edf >= 0)) throw InputError("NoiseFitOptions.floor_min_edf must be >= 0");
  if (!(support_min_edf >= 0)) throw InputError("NoiseFitOptions.support_min_edf must be >= 0");
  if (!std::isfinite(term_penalty)) throw InputError("NoiseFitOptions.term_penalty must be finite");
}

double ChiSquaredSurvival(double x, double dof) {
  if (!(dof > 0)) throw std::invalid_argument("ChiSquaredSurvival: dof > 0");
  if (!(x > 0)) return 1.0;
  if (std::isinf(x)) return 0.0;
  // Q(dof/2, x/2), computed as the upper tail itself: tiny tail probabilities keep their precision.
  return boost::math::gamma_q(0.5 * dof, 0.5 * x);
}

double ChiSquaredQuantile(double p, double dof) {
  if (!(p > 0 && p < 1) || !(dof > 0)) throw std::invalid_argument("ChiSquaredQuantile: p in (0,1), dof > 0");
  return 2 * boost::math::gamma_p_inv(0.5 * dof, p);
}

double OverlappingAvarEdf(AllanNoise noise, double n, double m) {
  if (!(n > 3) || !(m >= 1) || 2 * m > n) throw std::invalid_argument("OverlappingAvarEdf: need n > 3, 1 <= m <= n/2");
  double edf = 1;
  switch (noise) {
    case AllanNoise::kQuantization:  // white PM
      edf = (n + 1) * (n - 2 * m) / (2 * (n - m));
      break;
    case AllanNoise::kWhiteRate:  // white FM
      edf = (3 * (n - 1) / (2 * m) - 2 * (n - 2) / n) * 4 * m * m / (4 * m * m + 5);
      break;
    case AllanNoise::kFlickerRate:  // flicker FM
      edf = m == 1 ? 2 * (n - 2) * (n - 2) / (2.3 * n - 4.9) : 5 * n * n / (4 * m * (n + 3 * m));
      break;
    case AllanNoise::kRandomWalkRate:  // random-walk FM
      edf = (n - 2) / m * ((n - 1) * (n - 1) - 3 * m * (n - 1) + 4 * m * m) / ((n - 3) * (n - 3));
      break;
  }
  return std::max(edf, 1.0);  // the approximations are not meant below one degree of freedom
}

double ConservativeAvarEdf(AllanNoise noise, double n, double m) {
  // A steep fall of a few long-tau points is a fluke, not quantisation noise, and the white-phase
  // formula would then claim ~n/2 degrees of freedom: never exceed the white-rate value.
  return std::min(OverlappingAvarEdf(noise, n, m), OverlappingAvarEdf(AllanNoise::kWhiteRate, n, m));
}

std::vector<AllanNoise> IdentifyNoiseBySlope(const std::vector<double>& tau, const std::vector<double>& adev) {
  const size_t k = tau.size();
  std::vector<AllanNoise> out(k, AllanNoise::kWhiteRate);
  if (k < 2) return out;
  for (size_t i = 0; i < k; ++i) {
    // Slope of log avar over about an octave each side, clipped to the curve.
    size_t a = i, b = i;
    while (a > 0 && tau[i] / tau[a] < 2) --a;
    while (b + 1 < k && tau[b] / tau[i] < 2) ++b;
    if (a == b) continue;
    if (!(adev[a] > 0) || !(adev[b] > 0)) continue;
    const double mu = 2 * std::log(adev[b] / adev[a]) / std::log(tau[b] / tau[a]);
    out[i] = mu < -1.5   ? AllanNoise::kQuantization
             : mu < -0.5 ? AllanNoise::kWhiteRate
             : mu < 0.5  ? AllanNoise::kFlickerRate
                         : AllanNoise::kRandomWalkRate;
  }
  return out;
}

void SetConfidenceIntervals(AllanCurve* c, double confidence) {
  const double tail = 0.5 * (1 - confidence);
  c->adev_lo.resize(c->adev.size());
  c->adev_hi.resize(c->adev.size());
  for (size_t i = 0; i < c->adev.size(); ++i) {
    // avar * edf / true ~ chi2(edf) (NIST SP 1065, confidence intervals of the Allan variance).
    const double e = c->edf[i];
    c->adev_lo[i] = c->adev[i] * std::sqrt(e / ChiSquaredQuantile(1 - tail, e));
    c->adev_hi[i] = c->adev[i] * std::sqrt(e / ChiSquaredQuantile(tail, e));
  }
}

AllanCurve OverlappingAllanDeviation(const std::vector<double>& rate, double fs, const AllanOptions& options) {
  options.Check();
  if (!(fs > 0) || !std::isfinite(fs)) throw InputError("OverlappingAllanDeviation: sample rate must be > 0");
  const size_t n = rate.size();
  if (n < options.min_samples) {
    throw InputError("too few samples for an Allan deviation: " + std::to_string(n) + " < " +
                     std::to_string(options.min_samples));
  }
  const double tau0 = 1 / fs;
  // Phase (integrated rate) of the mean-removed rate: the mean does not change the Allan variance and
  // removing it keeps the second differences of the phase free of cancellation.
  long double mean = 0;
  for (double r : rate) {
    if (!std::isfinite(r)) throw InputError("OverlappingAllanDeviation: non-finite sample");
    mean += r;
  }
  mean /= n;
  std::vector<double> x(n + 1, 0.0);
  long double acc = 0;
  for (size_t i = 0; i < n; ++i) {
    acc += (static_cast<long double>(rate[i]) - mean) * tau0;
    x[i + 1] = static_cast<double>(acc);
  }
  // Log-spaced integer averaging factors m = 1 .. floor((n-1)/2) (at least one full second difference).
  std::vector<size_t> ms;
  const size_t m_max = (n - 1) / 2;
  for (int k = 0;; ++k) {
    const size_t m =
        static_cast<size_t>(std::llround(std::pow(10.0, static_cast<double>(k) / options.points_per_decade)));
    if (m > m_max) break;
    if (ms.empty() || m != ms.back()) ms.push_back(m);
  }
  AllanCurve c;
  c.sample_rate_hz = fs;
  c.n = n;
  c.edf_source = "formula";
  const double np = static_cast<double>(n + 1);  // phase points
  for (size_t m : ms) {
    // Overlapping estimator on phase x (NIST SP 1065): avar = sum (x[i+2m] - 2x[i+m] + x[i])^2 / (2 tau^2 (N - 2m)).
    const size_t terms = n + 1 - 2 * m;
    double sum = 0;
    const double* p = x.data();
    for (size_t i = 0; i < terms; ++i) {
      const double d = p[i + 2 * m] - 2 * p[i + m] + p[i];
      sum += d * d;
    }
    const double tau = m * tau0;
    const double avar = sum / (2 * tau * tau * terms);
    c.tau_s.push_back(tau);
    c.adev.push_back(std::sqrt(avar));
  }
  c.noise = IdentifyNoiseBySlope(c.tau_s, c.adev);
  for (size_t i = 0; i < ms.size(); ++i)
    c.edf.push_back(ConservativeAvarEdf(c.noise[i], np, static_cast<double>(ms[i])));
  SetConfidenceIntervals(&c, options.confidence);
  return c;
}

double NoiseFit::ModelAdev(double tau) const {
  const double q = quantization.value, nn = arw.value, b = bias_instability.value, k = rrw.value, r = rate_ramp.value;
  return std::sqrt(3 * q * q / (tau * tau) + nn * nn / tau + kFlickerFactor * b * b + k * k * tau / 3 +
                   r * r * tau * tau / 2);
}

namespace {

// The curve's points to fit: positive tau, ADEV and edf within the options' tau range.
std::vector<size_t> PointsToFit(const AllanCurve& curve, const NoiseFitOptions& options) {
  std::vector<size_t> idx;
  for (size_t i = 0; i < curve.tau_s.size(); ++i) {
    const double t = curve.tau_s[i];
    if (!(t > 0) || !(curve.adev[i] > 0) || !(curve.edf[i] > 0)) continue;
    if (options.tau_min_s > 0 && t < options.tau_min_s) continue;
    if (options.tau_max_s > 0 && t > options.tau_max_s) continue;
    idx.push_back(i);
  }
  return idx;
}

// The floor (ADEV minimum) into fit->adev_min..., among points with at least floor_min_edf degrees of
// freedom (a lone long-tau dip is noise), or among all points when none has that many.
void FindFloor(const AllanCurve& curve, double floor_min_edf, NoiseFit* fit) {
  const size_t k = curve.tau_s.size();
  bool any_well_determined = false;
  for (size_t i = 0; i < k; ++i) any_well_determined |= curve.adev[i] > 0 && curve.edf[i] >= floor_min_edf;
  for (size_t i = 0; i < k; ++i) {
    if (any_well_determined && !(curve.edf[i] >= floor_min_edf)) continue;
    if (curve.adev[i] > 0 && (fit->adev_min == 0 || curve.adev[i] < fit->adev_min)) {
      fit->adev_min = curve.adev[i];
      fit->tau_at_min_s = curve.tau_s[i];
      // 1-sigma of an ADEV point: adev / sqrt(2 edf) (delta method on the chi-squared avar).
      fit->adev_min_sigma = curve.edf[i] > 0 ? curve.adev[i] / std::sqrt(2 * curve.edf[i]) : 0;
      // Still falling there: no flat region was reached, so the floor only bounds B from above.
      fit->adev_min_is_upper_bound = i < curve.noise.size() && (curve.noise[i] == AllanNoise::kWhiteRate ||
                                                                curve.noise[i] == AllanNoise::kQuantization);
    }
  }
}

// Basis of the IEEE 952 Annex C model in the squared coefficients c = (Q^2, N^2, B^2, K^2, R^2).
double NoiseBasis(int j, double t) {
  switch (j) {
    case 0:
      return 3 / (t * t);
    case 1:
      return 1 / t;
    case 2:
      return kFlickerFactor;
    case 3:
      return t / 3;
    default:
      return t * t / 2;
  }
}

// The linear system of the fitted points: basis a (p x 5), avar y, edf, and each point's octave share.
struct AvarSystem {
  Eigen::MatrixXd a;
  Eigen::VectorXd y, edf, share;
};

AvarSystem MakeAvarSystem(const AllanCurve& curve, const std::vector<size_t>& idx) {
  const size_t p = idx.size();
  AvarSystem s;
  s.a.resize(p, 5);
  s.y.resize(p);
  s.edf.resize(p);
  s.share.resize(p);
  for (size_t r = 0; r < p; ++r) {
    const size_t i = idx[r];
    const double t = curve.tau_s[i];
    for (int j = 0; j < 5; ++j) s.a(r, j) = NoiseBasis(j, t);
    s.y(r) = curve.adev[i] * curve.adev[i];
    s.edf(r) = curve.edf[i];
    // Share of an octave this point stands for: half the log2 distance to its neighbours, at most 1.
    const double lo = r > 0 ? std::log2(t / curve.tau_s[idx[r - 1]]) : 1e9;
    const double hi = r + 1 < p ? std::log2(curve.tau_s[idx[r + 1]] / t) : 1e9;
    s.share(r) = std::min(1.0, 0.5 * (std::min(lo, 1.0) + std::min(hi, 1.0)));
  }
  return s;
}

// A set of active terms with its coefficients (all five, zero outside the set) and their covariance.
struct TermSetFit {
  std::vector<int> set;
  Eigen::VectorXd c = Eigen::VectorXd::Zero(5);
  Eigen::MatrixXd cov;
  double cost = 0;  // weighted squared residual + penalty per term; infinite when no set is feasible
};

// Exact NNLS over five unknowns with weights w: the best feasible (all coefficients positive)
// least-squares solution over all active sets of enabled terms, each term paying `penalty`.
TermSetFit BestTermSet(const AvarSystem& s, const Eigen::VectorXd& w, const bool enabled[5], double penalty) {
  const size_t p = static_cast<size_t>(s.y.size());
  TermSetFit best;
  best.cost = std::numeric_limits<double>::infinity();
  for (int mask = 1; mask < 32; ++mask) {
    std::vector<int> set;
    bool ok = true;
    for (int j = 0; j < 5; ++j) {
      if (mask & (1 << j)) {
        if (!enabled[j]) ok = false;
        set.push_back(j);
      }
    }
    if (!ok || set.size() >= p) continue;
    const int q = static_cast<int>(set.size());
    Eigen::MatrixXd as(p, q);
    for (int j = 0; j < q; ++j) as.col(j) = s.a.col(set[j]);
    // Weighted, column-normalised system: the basis spans many decades.
    Eigen::VectorXd sw = w.cwiseSqrt();
    Eigen::MatrixXd aw = sw.asDiagonal() * as;
    Eigen::VectorXd scale = aw.colwise().norm().transpose();
    for (int j = 0; j < q; ++j) aw.col(j) /= scale(j);
    const Eigen::VectorXd yw = sw.cwiseProduct(s.y);
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(aw);
    if (qr.rank() < q) continue;
    const Eigen::VectorXd cs = qr.solve(yw);
    Eigen::VectorXd c = cs.cwiseQuotient(scale);
    if ((c.array() <= 0).any()) continue;
    // Each term must pay for itself (Schwarz's criterion over the effective number of points), so
    // a term enters only where it is significant and does not trade off against the true one.
    const double cost = (aw * cs - yw).squaredNorm() + penalty * q;
    if (cost < best.cost) {
      best.cost = cost;
      best.set = set;
      best.c.setZero();
      for (int j = 0; j < q; ++j) best.c(set[j]) = c(j);
      const Eigen::MatrixXd ata = aw.transpose() * aw;
      Eigen::MatrixXd cov_s = ata.inverse();
      best.cov = Eigen::MatrixXd::Zero(5, 5);
      for (int u = 0; u < q; ++u)
        for (int v = 0; v < q; ++v) best.cov(set[u], set[v]) = cov_s(u, v) / (scale(u) * scale(v));
    }
  }
  return best;
}

// Iteratively reweighted: weights from the data in the first pass, then from the previous pass'
// model (left in *model).
TermSetFit FitTermsIteratively(const AvarSystem& s, const bool enabled[5], double penalty,
                               const NoiseFitOptions& options, Eigen::VectorXd* model) {
  const size_t p = static_cast<size_t>(s.y.size());
  *model = s.y;
  TermSetFit best;
  for (int iter = 0; iter < options.iterations; ++iter) {
    // var(avar_i) = 2 avar_i^2 / edf_i (chi-squared); weight scaled by the point's octave share.
    Eigen::VectorXd w(p);
    // A relative floor on the ADEV error stands for model error (real flicker is not flat, filters
    // shape the shortest taus), so that points with huge edf do not alone decide the fit.
    const double floor2 = 4 * options.model_error * options.model_error;
    for (size_t r = 0; r < p; ++r) w(r) = s.share(r) / ((*model)(r) * (*model)(r) * (2 / s.edf(r) + floor2));
    best = BestTermSet(s, w, enabled, penalty);
    if (!std::isfinite(best.cost)) break;
    *model = s.a * best.c;
  }
  return best;
}

// One term's value, sigma (inflated by the misfit), the tau range where it dominates the model, and
// whether it is significant.
void ReportTerm(const AllanCurve& curve, const std::vector<size_t>& idx, const AvarSystem& s,
                const Eigen::VectorXd& model, const TermSetFit& best, int j, double inflate, double dominance,
                double support_min_edf, NoiseTerm* term) {
  NoiseTerm& t = *term;
  const double c = best.c(j);
  if (c <= 0) return;
  t.value = std::sqrt(c);
  t.sigma = std::sqrt(std::max(0.0, best.cov(j, j) * inflate)) / (2 * t.value);  // delta method on sqrt
  int support = 0;
  bool any_well_determined = false;
  for (size_t r = 0; r < idx.size(); ++r) any_well_determined |= curve.edf[idx[r]] >= support_min_edf;
  for (size_t r = 0; r < idx.size(); ++r) {
    const double f = s.a(r, j) * c / model(r);
    t.max_fraction = std::max(t.max_fraction, f);
    if (f >= dominance) {
      support += !any_well_determined || curve.edf[idx[r]] >= support_min_edf;
      const double tau = curve.tau_s[idx[r]];
      if (t.tau_min_s == 0 || tau < t.tau_min_s) t.tau_min_s = tau;
      t.tau_max_s = std::max(t.tau_max_s, tau);
    }
  }
  // One dominated point (often the last, with few degrees of freedom) is not support.
  t.significant = support >= 2 && t.value > 2 * t.sigma;
}

}  // namespace

NoiseFit FitNoiseTerms(const AllanCurve& curve, const NoiseFitOptions& options) {
  options.Check();
  NoiseFit fit;
  const size_t k = curve.tau_s.size();
  if (curve.adev.size() != k || curve.edf.size() != k) throw std::invalid_argument("FitNoiseTerms: ragged curve");
  const std::vector<size_t> idx = PointsToFit(curve, options);
  FindFloor(curve, options.floor_min_edf, &fit);
  const bool enabled[5] = {options.fit_quantization, true, options.fit_bias_instability, true, options.fit_rate_ramp};
  int n_enabled = 0;
  for (bool e : enabled) n_enabled += e;
  if (static_cast<int>(idx.size()) < n_enabled + 1) {
    fit.status = FitStatus::kTooFewPoints;
    fit.message =
        "need at least " + std::to_string(n_enabled + 1) + " positive Allan points, have " + std::to_string(idx.size());
    if (k > 0 && std::all_of(curve.adev.begin(), curve.adev.end(), [](double v) { return v == 0; })) {
      fit.message += " (the Allan deviation is zero at every tau: a constant signal)";
    }
    return fit;
  }
  const AvarSystem s = MakeAvarSystem(curve, idx);
  const double penalty = options.term_penalty >= 0 ? options.term_penalty : std::log(std::max(2.0, s.share.sum()));
  Eigen::VectorXd model;
  const TermSetFit best = FitTermsIteratively(s, enabled, penalty, options, &model);
  if (!std::isfinite(best.cost) || best.set.empty()) {
    fit.status = FitStatus::kTooFewPoints;
    fit.message = "no non-negative fit of the noise model";
    return fit;
  }
  // Degrees of freedom from the octave shares (the effective number of independent points).
  const double dof = std::max(1.0, s.share.sum() - static_cast<double>(best.set.size()));
  fit.chi2_per_dof = (best.cost - penalty * static_cast<double>(best.set.size())) / dof;
  // Model misfit (e.g. flicker that is not flat, unmodelled terms) widens the uncertainties.
  const double inflate = curve.edf_source == "assumed" ? fit.chi2_per_dof : std::max(1.0, fit.chi2_per_dof);
  fit.points_used = idx.size();
  NoiseTerm* terms[5] = {&fit.quantization, &fit.arw, &fit.bias_instability, &fit.rrw, &fit.rate_ramp};
  for (int j = 0; j < 5; ++j) {
    ReportTerm(curve, idx, s, model, best, j, inflate, options.dominance, options.support_min_edf, terms[j]);
  }
  fit.model_adev.resize(k);
  for (size_t i = 0; i < k; ++i) fit.model_adev[i] = curve.tau_s[i] > 0 ? fit.ModelAdev(curve.tau_s[i]) : 0;
  fit.status = FitStatus::kFitted;
  return fit;
}

}  // namespace ssiu
