// How detectable is the random telegraph bias of the out-of-vocabulary tests (issue 18)? Oracles with the
// generator's truth, written for the test (no code shared with the library), against what `discover gyro`
// says on the same cases (docs/discrepancy.md, "Telegraph detectability").
#include <Eigen/Dense>
#include <algorithm>
#include <cstdio>
#include <functional>
#include <tuple>

#include "discover_gyro_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

constexpr double kBinS = 43.2;  // 1000 bins of the 12 h static log, as the library's
constexpr int kBins = 1000;
constexpr double kWanderTauMaxS = 1800;  // the library's bound on the wander (its null class)

// Gaussian log-likelihood of y under white (vw) + first-order Gauss-Markov (vg, phi) noise plus the
// regressors x (coefficients profiled out by GLS): a scalar Kalman filter's innovations whiten [x y].
double GaussMarkovLogLik(const VectorXd& y, const MatrixXd& x, double vw, double vg, double phi) {
  const int m = static_cast<int>(y.size()), k = static_cast<int>(x.cols());
  MatrixXd w(m, k + 1), state = MatrixXd::Zero(1, k + 1);
  double p = vg, log_s = 0;
  for (int i = 0; i < m; ++i) {
    if (i > 0) p = phi * phi * p + vg * (1 - phi * phi), state *= phi;
    const double s = p + vw;
    Eigen::RowVectorXd row(k + 1);
    row << x.row(i), y(i);
    const Eigen::RowVectorXd innov = row - state;
    w.row(i) = innov / std::sqrt(s);
    state += (p / s) * innov;
    p *= vw / s;
    log_s += std::log(s);
  }
  const MatrixXd xw = w.leftCols(k);
  const VectorXd yw = w.col(k);
  const VectorXd beta = (xw.transpose() * xw).ldlt().solve(xw.transpose() * yw);
  return -0.5 * ((yw - xw * beta).squaredNorm() + log_s + m * std::log(2 * kPi));
}

struct GaussMarkov {
  double vw = 0, vg = 0, phi = 0, loglik = 0;
};

// Maximum likelihood over ln vw, ln vg and the correlation time (bin/10 .. kWanderTauMaxS): cyclic
// coordinate ascent, a golden-section search along each coordinate, until a sweep gains < 1e-3 nats.
GaussMarkov FitGaussMarkov(const VectorXd& y, const MatrixXd& x) {
  const double v = (y.array() - y.mean()).square().mean();
  double q[3] = {std::log(0.7 * v), std::log(0.3 * v), std::log(600.0)};
  const double lo[3] = {q[0] - 8, q[1] - 12, std::log(kBinS / 10)},
               hi[3] = {q[0] + 3, q[1] + 3, std::log(kWanderTauMaxS)};
  auto ll = [&](const double* qq) {
    return GaussMarkovLogLik(y, x, std::exp(qq[0]), std::exp(qq[1]), std::exp(-kBinS / std::exp(qq[2])));
  };
  double best = ll(q);
  for (int sweep = 0; sweep < 12; ++sweep) {
    const double before = best;
    for (int c = 0; c < 3; ++c) {
      double a = lo[c], b = hi[c];
      const double g = 0.5 * (std::sqrt(5.0) - 1);
      double t[3] = {q[0], q[1], q[2]};
      auto at = [&](double u) {
        t[c] = u;
        return ll(t);
      };
      double u1 = b - g * (b - a), u2 = a + g * (b - a), f1 = at(u1), f2 = at(u2);
      for (int it = 0; it < 40 && b - a > 1e-4; ++it) {
        if (f1 > f2) {
          b = u2, u2 = u1, f2 = f1, u1 = b - g * (b - a), f1 = at(u1);
        } else {
          a = u1, u1 = u2, f1 = f2, u2 = a + g * (b - a), f2 = at(u2);
        }
      }
      const double u = f1 > f2 ? u1 : u2, f = std::max(f1, f2);
      if (f > best) best = f, q[c] = u;
    }
    if (best - before < 1e-3) break;
  }
  return {std::exp(q[0]), std::exp(q[1]), std::exp(-kBinS / std::exp(q[2])), best};
}

// Log-likelihood of v under a two-state hidden Markov model with the given levels, emission variance and
// switching probability per bin (both ways), forward algorithm with scaling (Rabiner 1989).
double TelegraphLogLik(const VectorXd& v, double lo, double hi, double s2, double a) {
  double f_lo = 0.5, ll = -0.5 * v.size() * std::log(2 * kPi * s2);
  for (int i = 0; i < v.size(); ++i) {
    const double prior = i == 0 ? 0.5 : f_lo * (1 - a) + (1 - f_lo) * a;
    const double d0 = v(i) - lo, d1 = v(i) - hi;
    const double e0 = prior * std::exp(-0.5 * d0 * d0 / s2), e1 = (1 - prior) * std::exp(-0.5 * d1 * d1 / s2);
    f_lo = e0 / (e0 + e1);
    ll += std::log(e0 + e1);
  }
  return ll;
}

struct Oracle {
  double known_times_2llr = 0;  // 2 ln LR of the true two-level signal (switch times known) vs the wander
  double np_statistic = 0, np_p = 1;
};

// Two oracles on the static log's bins y (s: the true telegraph, +-0.5, bin means):
// - switch times known: 2 ln LR of a wander + the two-level regressor s against a wander alone (both by
//   maximum likelihood): how clear the effect is to someone who knows when it switched;
// - Neyman-Pearson: ln L(telegraph at its true levels, switching rate and emission variance) - ln L(the
//   wander fitted to y), its p-value by simulation from that wander (held; 20000 replicates at most,
//   stop at 20 exceedances). By the Neyman-Pearson lemma no test of the wander against this telegraph
//   has more power, and the library's test has to fit the telegraph too.
Oracle TelegraphOracle(const testing::GyroCase& c, const VectorXd& y, const VectorXd& s, double dwell_s,
                       uint64_t seed) {
  Oracle o;
  const MatrixXd one = MatrixXd::Ones(y.size(), 1);
  MatrixXd two(y.size(), 2);
  two << one, s;
  const GaussMarkov h0 = FitGaussMarkov(y, one), h1 = FitGaussMarkov(y, two);
  o.known_times_2llr = 2 * (h1.loglik - h0.loglik);
  const double amp = c.truth.at("telegraph_levels_dph"), s_mean = s.mean();
  const double s2 = c.arw_dph_sqrt_s * c.arw_dph_sqrt_s / kBinS + c.wander_dph * c.wander_dph;
  const double a = 1 - std::exp(-kBinS / dwell_s);
  auto stat = [&](VectorXd v) {
    v.array() -= v.mean();
    return TelegraphLogLik(v, amp * (-0.5 - s_mean), amp * (0.5 - s_mean), s2, a) -
           GaussMarkovLogLik(v, one, h0.vw, h0.vg, h0.phi);
  };
  o.np_statistic = stat(y);
  Rng rng(seed);
  const double sd_step = std::sqrt(h0.vg * (1 - h0.phi * h0.phi)), sd_w = std::sqrt(h0.vw);
  int exceed = 0, done = 0;
  VectorXd z(y.size());
  while (done < 20000 && exceed < 20) {
    double x = std::sqrt(h0.vg) * rng.Normal();
    for (int i = 0; i < z.size(); ++i) {
      if (i > 0) x = h0.phi * x + sd_step * rng.Normal();
      z(i) = x + sd_w * rng.Normal();
    }
    exceed += stat(z) >= o.np_statistic;
    ++done;
  }
  o.np_p = (exceed + 1.0) / (done + 1.0);
  return o;
}

TEST(DiscoverGyroLong, TelegraphDetectabilityOracle) {
  // The cases of TelegraphFreshSeedsAndFasterSwitching and the telegraphs of OutOfVocabularyIsUnexplained.
  std::vector<std::tuple<std::string, uint64_t>> cases;
  for (const auto& [variant, n, seed0] :
       std::vector<std::tuple<std::string, int, uint64_t>>{{"telegraph", 24, 5151},
                                                           {"telegraph_fast", 16, 6161},
                                                           {"telegraph", 24, 8181},
                                                           {"telegraph_fast", 16, 9191}}) {
    for (int i = 0; i < n; ++i) cases.emplace_back(variant, seed0 + 7919 * i);
  }
  for (int k = 0; k < 8; ++k) cases.emplace_back("telegraph", 272727 + 7919 * (4 * k + 2));
  // Outcome counts per band of the Neyman-Pearson p: <= 1e-4, <= 1e-3, <= 1e-2, above.
  const double bands[] = {1e-4, 1e-3, 1e-2, 2};
  std::map<int, std::map<std::string, int>> by_band;
  double min_known = 1e300, max_known = 0;
  for (const auto& [variant, seed] : cases) {
    const testing::GyroCase c = testing::MakeGyroCase(variant, seed);
    const GyroBenchLog& log = c.logs.front();
    VectorXd y = VectorXd::Zero(kBins), s = VectorXd::Zero(kBins), n = VectorXd::Zero(kBins);
    for (size_t i = 0; i < log.t_s.size(); ++i) {
      const int k = std::min(kBins - 1, static_cast<int>(log.t_s[i] / kBinS));
      const auto after = std::upper_bound(c.telegraph_switch_s.begin(), c.telegraph_switch_s.end(), log.t_s[i]);
      y(k) += log.w_dph[i] - log.ref_dph[i];
      s(k) += static_cast<double>((after - c.telegraph_switch_s.begin()) % 2) - 0.5;
      n(k) += 1;
    }
    y.array() /= n.array();
    s.array() /= n.array();
    const Oracle o = TelegraphOracle(c, y, s, variant == "telegraph" ? 2400 : 1200, seed + 1);
    const std::string found = DiscoverGyro(c.logs, GyroDiscoverOptions{}).cause;
    const int band = static_cast<int>(
        std::find_if(std::begin(bands), std::end(bands), [&](double b) { return o.np_p <= b; }) - std::begin(bands));
    ++by_band[band][found == "unexplained" || found == "none" ? found : "wrongly named"];
    min_known = std::min(min_known, o.known_times_2llr), max_known = std::max(max_known, o.known_times_2llr);
    std::printf(
        "%s %llu: levels %.3f dph apart, %zu switches; switch times known 2 ln LR %.1f; Neyman-Pearson "
        "statistic %.2f p %.2g; found %s\n",
        variant.c_str(), static_cast<unsigned long long>(seed), c.truth.at("telegraph_levels_dph"),
        c.telegraph_switch_s.size(), o.known_times_2llr, o.np_statistic, o.np_p, found.c_str());
  }
  std::printf("switch times known: 2 ln LR %.0f-%.0f\n", min_known, max_known);
  const char* names[] = {"p <= 1e-4", "1e-4 < p <= 1e-3", "1e-3 < p <= 1e-2", "p > 1e-2"};
  for (const auto& [band, counts] : by_band) {
    std::printf("Neyman-Pearson %s:", names[band]);
    for (const auto& [what, k] : counts) std::printf(" %s %d", what.c_str(), k);
    std::printf("\n");
  }
  // Where even the most powerful test with every parameter known is beyond 1e-4 per log (10x below the
  // library's 1e-3 per log: 0.01 over two logs and five tests): measured 50/56 `unexplained` (none 5,
  // wrongly named 1) with the telegraph-in-wander statistic and the family of nine (51/56 with five; 50/56
  // with the HMM's and five, whose fitted parameters cost power: its p on the 5 misses 0.003-0.035); a
  // regression floor at 85 %.
  auto count = [&](int band, const std::string& what) {
    return by_band[band].count(what) ? by_band[band].at(what) : 0;
  };
  const int clear = count(0, "unexplained") + count(0, "none") + count(0, "wrongly named");
  EXPECT_GE(count(0, "unexplained"), 0.85 * clear);
  int wrong = 0;
  for (int b = 0; b < 4; ++b) wrong += count(b, "wrongly named");
  EXPECT_LE(wrong, 0.05 * cases.size());
}

}  // namespace
}  // namespace ssiu
