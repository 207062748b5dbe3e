// The photometric tests of a hypothesis (docs/identify.md, step 5): the triangle's zero-point test
// against the triples the brightness-ordered search could have paired, and the evidence of the extra
// matches, each an e-value of mean 1 under a chance match.
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "identify/identify.h"
#include "identify/identify_internal.h"

namespace ssiu {
namespace identify_internal {

// The harmonic number H_T = sum_{k <= T} 1/k: summed below 10^4, else ln T + gamma + 1/(2T) - 1/(12T^2)
// (Abramowitz & Stegun 6.3.18; the next term, 1/(120 T^4), is below 1e-17 there).
double Harmonic(double t) {
  if (t < 1e4) {
    double h = 0;
    for (double k = t; k >= 1; --k) h += 1 / k;  // smallest terms first
    return h;
  }
  return std::log(t) + 0.57721566490153286 + 1 / (2 * t) - 1 / (12 * t * t);
}

// The triangle's photometric p-value. The search takes triangles brightest first: every triangle whose
// faintest vertex is the c-th brightest centroid comes before those of the (c+1)-th (step 1), and the
// geometry alone (positions, independent of the fluxes under a chance match) picks which two of the
// c - 1 brighter ones join it and which vertex each becomes. So under the null hypothesis the
// triangle's fluxes are, given its faintest, a uniformly drawn ordered triple of the T = 3 (c-1)(c-2)
// that hold the faintest and two of the brighter, and p = the share of those whose zero points
// z = ln f + 0.4 ln(10) V against the triangle's magnitudes scatter (sum of squares about their mean,
// which unlike the range has no ties between triples) no more than the triangle's own. ln_brighter:
// the c - 1 brighter centroids' ln fluxes, sorted ascending (the triangle's other two among them).
// Counted in O(c log c): with the faintest at one vertex and a brighter one at another, the z that
// keep the sum of squares <= q at the third form the interval (z_i + z_j) / 2 +- sqrt(1.5 q - 0.75
// (z_i - z_j)^2), one range of the sorted list. Returns p and T.
std::pair<double, double> TriangleZeroPointP(const double* pair_flux, const double* pair_mag,
                                             const ScratchVec<double>& ln_brighter) {
  const double k_mag = 0.4 * std::log(10.0);
  double z[3], c[3];
  int faintest = 0;
  for (int i = 0; i < 3; ++i) {
    c[i] = k_mag * pair_mag[i];
    z[i] = std::log(pair_flux[i]) + c[i];
    if (pair_flux[i] < pair_flux[faintest]) faintest = i;
  }
  const double mean = (z[0] + z[1] + z[2]) / 3;
  const double q =
      ((z[0] - mean) * (z[0] - mean) + (z[1] - mean) * (z[1] - mean) + (z[2] - mean) * (z[2] - mean)) * (1 + 1e-9) +
      1e-15;  // the triangle's own triple always counts
  const double x_faint = std::log(pair_flux[faintest]);
  const auto begin = ln_brighter.begin(), end = ln_brighter.end();
  double count = 0;
  for (int p = 0; p < 3; ++p) {  // the faintest at vertex p, a brighter one at q, the third at r
    const int q_v = (p + 1) % 3, r_v = (p + 2) % 3;
    const double zp = x_faint + c[p];
    for (auto b = begin; b != end; ++b) {
      const double zq = *b + c[q_v];
      const double h2 = 1.5 * q - 0.75 * (zp - zq) * (zp - zq);
      if (h2 < 0) continue;
      const double mid = 0.5 * (zp + zq) - c[r_v], half = std::sqrt(h2);
      const auto first = std::lower_bound(begin, end, mid - half);
      const auto last = std::upper_bound(first, end, mid + half);
      count += static_cast<double>(last - first) - (b >= first && b < last);  // distinct from the one at q
    }
  }
  const double n = static_cast<double>(ln_brighter.size());
  const double t = 3 * n * (n - 1);
  return {t > 0 ? std::clamp(count / t, 0.0, 1.0) : 1.0, t};
}

// PhotometricEvidence over n pairs and n_other other fluxes, with scratch vectors for the zero points.
double PhotometricEvidenceOf(const double* pair_flux, const double* pair_mag, size_t n, const double* other_flux,
                             size_t n_other, ScratchVec<double>* zp, ScratchVec<double>* z) {
  // The triangle: e = 1 / (p H_T), T = 3 (c-1)(c-2) ordered triples (TriangleZeroPointP): p is
  // (super-)uniform on {1/T, ..., 1}, so E[1/p] <= H_T and the mean of e is at most 1. The brighter
  // ones: the verification centroids at least as bright as the triangle's faintest, less that vertex.
  z->clear();
  const double f_min = std::min({pair_flux[0], pair_flux[1], pair_flux[2]});
  bool skipped = false;  // the faintest vertex itself (once, should another flux equal it)
  for (size_t i = 0; i < n; ++i) {
    if (i < 3 && !skipped && pair_flux[i] == f_min) {
      skipped = true;
      continue;
    }
    if (pair_flux[i] >= f_min) z->push_back(std::log(pair_flux[i]));
  }
  for (size_t i = 0; i < n_other; ++i)
    if (other_flux[i] >= f_min) z->push_back(std::log(other_flux[i]));
  std::sort(z->begin(), z->end());
  const auto [p_tri, t_tri] = TriangleZeroPointP(pair_flux, pair_mag, *z);
  double e = t_tri > 0 ? 1.0 / (p_tri * Harmonic(t_tri)) : 1.0;
  const double k_mag = 0.4 * std::log(10.0);
  zp->clear();  // ln f + 0.4 ln(10) V of the pairs so far: the zero point
  for (int i = 0; i < 3; ++i) zp->push_back(std::log(pair_flux[i]) + k_mag * pair_mag[i]);
  for (size_t i = 3; i < n; ++i) {
    z->assign(zp->begin(), zp->end());
    std::sort(z->begin(), z->end());
    const size_t h = z->size() / 2;
    const double ln_k = z->size() % 2 ? (*z)[h] : 0.5 * ((*z)[h - 1] + (*z)[h]);
    const double pred = ln_k - k_mag * pair_mag[i];
    const double d = std::abs(std::log(pair_flux[i]) - pred);
    // The pool: this match and the later ones, and the centroids in no pair (K counts ties in).
    int pool = 0, within = 0;
    auto count = [&](double f) { ++pool, within += std::abs(std::log(f) - pred) <= d; };
    for (size_t q = i; q < n; ++q) count(pair_flux[q]);
    for (size_t q = 0; q < n_other; ++q) count(other_flux[q]);
    double h_n = 0, s_n = 0;
    for (int k = 1; k <= pool; ++k) h_n += 1.0 / k, s_n += 1.0 / (static_cast<double>(k) * k);
    const double kk = std::max(1, within);
    // The mean of two calibrators, each of mean 1 for K uniform on {1..N}: 1 / (p H_N) and the steeper
    // N / (K^2 S_N), S_N = sum 1/k^2 (~N / 1.64 for K = 1 instead of N / H_N, ~N / 4.3 at N = 40; it
    // falls faster with K, so the mean keeps most of the harmonic one's value for noisy fluxes).
    e *= 0.5 * (pool / (kk * h_n) + pool / (kk * kk * s_n));
    zp->push_back(std::log(pair_flux[i]) + k_mag * pair_mag[i]);
  }
  return e;
}

}  // namespace identify_internal

double PhotometricEvidence(const std::vector<double>& pair_flux, const std::vector<double>& pair_mag,
                           const std::vector<double>& other_flux) {
  if (pair_flux.size() < 3 || pair_flux.size() != pair_mag.size())
    throw InputError("photometry", "need >= 3 pairs with a magnitude each");
  ScratchVec<double> zp, z;
  return identify_internal::PhotometricEvidenceOf(pair_flux.data(), pair_mag.data(), pair_flux.size(),
                                                  other_flux.data(), other_flux.size(), &zp, &z);
}

}  // namespace ssiu
