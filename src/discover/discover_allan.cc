#include "discover/discover_allan.h"

#include <Eigen/Dense>
#include <cmath>

#include "core/error.h"

namespace ssiu {

void AllanDiscrepancyOptions::Check() const {
  if (!(sigmas > 0)) throw InputError("options", "sigmas must be > 0");
}

AllanDiscrepancy CompareAllanToDefaultModel(const AllanCurve& curve, const AllanDiscrepancyOptions& options) {
  options.Check();
  const size_t n = curve.tau_s.size();
  if (n < 4) throw InputError("", "Allan curve has fewer than 4 points");
  AllanDiscrepancy r;
  // 1-sigma of each ADEV point: from its edf (sigma_avar / avar = sqrt(2 / edf)), with the same
  // 2 % model-error floor as FitNoiseTerms.
  const NoiseFitOptions nfo;
  std::vector<double> sig(n);
  for (size_t i = 0; i < n; ++i) {
    const double rel = curve.edf.size() == n && curve.edf[i] > 0 ? std::sqrt(2 / curve.edf[i]) / 2 : 0.05;
    sig[i] = curve.adev[i] * std::hypot(rel, nfo.model_error);
  }
  // Base: avar = N^2 / tau + c B^2, linear in (N^2, B^2); weights 1 / sigma_avar^2, with each point
  // counted for its share of an octave as in allan.h (overlapping points are correlated).
  const double c = 2 * std::log(2.0) / M_PI;
  Eigen::MatrixXd a(n, 2);
  Eigen::VectorXd y(n);
  for (size_t i = 0; i < n; ++i) {
    const double s_avar = 2 * curve.adev[i] * sig[i];
    double share = 1;
    if (n > 1) {
      const double lo =
          i > 0 ? std::log2(curve.tau_s[i] / curve.tau_s[i - 1]) : std::log2(curve.tau_s[1] / curve.tau_s[0]);
      const double hi = i + 1 < n ? std::log2(curve.tau_s[i + 1] / curve.tau_s[i]) : lo;
      share = std::min(1.0, 0.5 * (lo + hi));
    }
    const double w = std::sqrt(share) / s_avar;
    a(i, 0) = w / curve.tau_s[i];
    a(i, 1) = w * c;
    y(i) = w * curve.adev[i] * curve.adev[i];
  }
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
  bool in = false;
  for (size_t i = 0; i < n; ++i) {
    const double m = std::sqrt(p(0) / curve.tau_s[i] + c * p(1));
    r.base_adev.push_back(m);
    const double z = (m - curve.adev[i]) / sig[i];
    chi2 += z * z;
    const bool dep = std::abs(z) > options.sigmas;
    if (dep && !in) r.departures_s.push_back({curve.tau_s[i], curve.tau_s[i]});
    if (dep) r.departures_s.back().second = curve.tau_s[i];
    in = dep;
  }
  r.chi2_per_dof_before = chi2 / std::max<size_t>(1, n - 2);
  r.extended = FitNoiseTerms(curve, nfo);
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
  return r;
}

}  // namespace ssiu
