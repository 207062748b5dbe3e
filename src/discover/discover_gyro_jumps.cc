// Jumps between two levels in the residual of `ssiu discover gyro`: binary segmentation, the telegraph
// HMM, its likelihood inside the wander, and the parametric bootstrap behind the jumps test.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "core/rng.h"
#include "core/types.h"
#include "discover/discover_gyro_internal.h"

namespace ssiu::discover_internal {

namespace {

// Change points of v by binary segmentation (greedy: each time the split, over all current segments,
// with the largest white-noise CUSUM statistic n1 n2 / n (mean1 - mean2)^2; Vostrikova 1981), in the
// order found, up to kmax; change points on a grid of `grid` bins, every segment at least min_seg bins.
std::vector<int> BinarySegmentation(const VectorXd& v, int kmax, int min_seg, int grid) {
  const int m = static_cast<int>(v.size());
  std::vector<double> cum(m + 1, 0.0);
  for (int i = 0; i < m; ++i) cum[i + 1] = cum[i] + v(i);
  std::vector<int> cuts = {0, m}, found;
  for (int k = 0; k < kmax; ++k) {
    double best = 0;
    int best_pos = -1;
    for (size_t s = 0; s + 1 < cuts.size(); ++s) {
      const int a = cuts[s], b = cuts[s + 1];
      for (int c = (a + min_seg + grid - 1) / grid * grid; c <= b - min_seg; c += grid) {
        const double n1 = c - a, n2 = b - c;
        const double d = (cum[c] - cum[a]) / n1 - (cum[b] - cum[c]) / n2;
        const double stat = n1 * n2 / (n1 + n2) * d * d;
        if (stat > best) best = stat, best_pos = c;
      }
    }
    if (best_pos < 0) break;
    found.push_back(best_pos);
    cuts.insert(std::upper_bound(cuts.begin(), cuts.end(), best_pos), best_pos);
  }
  return found;
}

// Levels of residual v (TestResidual): binary segmentation into up to 17 pieces (change points on a grid
// of kJumpGrid bins, pieces >= 2 grid steps), each piece's mean level; the levels split into two groups
// (sorted, every threshold tried) to the smallest within-group variance. Returns that variance over the
// total (both weighted by the pieces' lengths): about 1 - 2/pi = 0.36 for the levels of a Gaussian
// wander, near 0 for a level switching between two values. *split: the threshold level.
constexpr int kJumpGrid = 4;

struct LevelSplit {
  double ratio = 1, threshold = 0, low = 0, high = 0;
  std::vector<int> cuts;  // sorted change points, with 0 and m
  std::vector<double> level;
};

LevelSplit SplitLevels(const VectorXd& v) {
  const int m = static_cast<int>(v.size());
  LevelSplit out;
  std::vector<int> cps = BinarySegmentation(v, std::min(16, m / 40), 2 * kJumpGrid, kJumpGrid);
  cps.push_back(0);
  cps.push_back(m);
  std::sort(cps.begin(), cps.end());
  out.cuts = cps;
  const int k = static_cast<int>(cps.size()) - 1;
  if (k < 3) return out;
  std::vector<std::pair<double, double>> lw;  // level, length
  for (int s = 0; s < k; ++s) {
    const int len = cps[s + 1] - cps[s];
    out.level.push_back(v.segment(cps[s], len).mean());
    lw.emplace_back(out.level.back(), len);
  }
  std::sort(lw.begin(), lw.end());
  double sw = 0, s1 = 0, s2 = 0;
  for (const auto& [x, w] : lw) sw += w, s1 += w * x, s2 += w * x * x;
  const double total = s2 - s1 * s1 / sw;
  if (!(total > 0)) return out;
  double aw = 0, a1 = 0, a2 = 0;
  for (int i = 0; i + 1 < k; ++i) {
    aw += lw[i].second, a1 += lw[i].second * lw[i].first, a2 += lw[i].second * lw[i].first * lw[i].first;
    const double bw = sw - aw, b1 = s1 - a1, b2 = s2 - a2;
    const double within = (a2 - a1 * a1 / aw) + (b2 - b1 * b1 / bw);
    if (within / total < out.ratio) {
      out.ratio = within / total;
      out.threshold = 0.5 * (lw[i].first + lw[i + 1].first);
      out.low = a1 / aw, out.high = b1 / bw;
    }
  }
  return out;
}

// A level that switches at random between two values, in white noise: the two-state Gaussian hidden
// Markov model (levels mu0 < mu1, one variance s2, switching probabilities a01, a10 per bin), fitted by
// EM (Baum et al. 1970; scaled forward-backward, Rabiner 1989 eqs. 92-93, 109-111), started from the two
// groups of levels of SplitLevels. loglik is conditional on the first bin, as NoiseModel::NegLogLik.
struct TelegraphHmm {
  double mu0 = 0, mu1 = 0, s2 = 1, a01 = 0.01, a10 = 0.01, loglik = 0;
};

TelegraphHmm FitTelegraphHmm(const VectorXd& v, const LevelSplit& start) {
  constexpr int kMaxIter = 30;
  const int m = static_cast<int>(v.size());
  TelegraphHmm h;
  h.mu0 = start.low, h.mu1 = start.high;
  int switches = 0;
  for (size_t s = 1; s < start.level.size(); ++s) {
    switches += (start.level[s] > start.threshold) != (start.level[s - 1] > start.threshold);
  }
  h.a01 = h.a10 = std::clamp((switches + 1.0) / m, 1e-4, 0.5);
  double ss = 0;
  for (int i = 0; i < m; ++i) {
    const double d = std::min(std::abs(v(i) - h.mu0), std::abs(v(i) - h.mu1));
    ss += d * d;
  }
  h.s2 = std::max(ss / m, 1e-300);
  std::vector<double> f0(m), c(m), b0(m), b1(m), post0(m);  // forward (state 0; state 1 is 1 - f0), scales
  double last = -std::numeric_limits<double>::infinity();
  for (int it = 0; it < kMaxIter; ++it) {
    // Forward: emissions relative to the larger of the two (the factor goes into the log-likelihood).
    const double a00 = 1 - h.a01, a11 = 1 - h.a10;
    double ll = 0;
    for (int i = 0; i < m; ++i) {
      const double d0 = v(i) - h.mu0, d1 = v(i) - h.mu1;
      const double l0 = -0.5 * d0 * d0 / h.s2, l1 = -0.5 * d1 * d1 / h.s2, mx = std::max(l0, l1);
      b0[i] = l0 >= l1 ? 1.0 : std::exp(l0 - l1), b1[i] = l1 > l0 ? 1.0 : std::exp(l1 - l0);
      const double p0 = i == 0 ? 0.5 : f0[i - 1] * a00 + (1 - f0[i - 1]) * h.a10;
      c[i] = p0 * b0[i] + (1 - p0) * b1[i];
      f0[i] = p0 * b0[i] / c[i];
      if (i > 0) ll += std::log(c[i]) + mx;
    }
    h.loglik = ll - 0.5 * (m - 1) * std::log(2 * kPi * h.s2);
    if (h.loglik - last < 1e-5 * m) break;  // 0.01 nats in 1000 bins; the null's spread is nats
    last = h.loglik;
    // Backward (scaled) with the sums of the M-step.
    double g0 = 0, g0v = 0, g1v = 0, x01 = 0, x10 = 0, g0t = 0, g1t = 0, r0 = 1, r1 = 1;
    for (int i = m - 1; i >= 0; --i) {
      if (i < m - 1) {
        const double e0 = b0[i + 1] * r0 / c[i + 1], e1 = b1[i + 1] * r1 / c[i + 1];
        x01 += f0[i] * h.a01 * e1, x10 += (1 - f0[i]) * h.a10 * e0;
        r0 = a00 * e0 + h.a01 * e1, r1 = h.a10 * e0 + a11 * e1;
      }
      const double q0 = f0[i] * r0, q1 = (1 - f0[i]) * r1;
      post0[i] = q0 / (q0 + q1);
      g0 += post0[i], g0v += post0[i] * v(i), g1v += (1 - post0[i]) * v(i);
      if (i < m - 1) g0t += post0[i], g1t += 1 - post0[i];
    }
    const double g1 = m - g0;
    if (!(g0t > 1e-6 && g1t > 1e-6)) break;  // one state left: the white-noise model
    h.mu0 = g0v / g0, h.mu1 = g1v / g1;
    h.a01 = std::clamp(x01 / g0t, 1e-6, 0.5), h.a10 = std::clamp(x10 / g1t, 1e-6, 0.5);
    double sq = 0;
    for (int i = 0; i < m; ++i) {
      const double d0 = v(i) - h.mu0, d1 = v(i) - h.mu1;
      sq += post0[i] * d0 * d0 + (1 - post0[i]) * d1 * d1;
    }
    h.s2 = std::max(sq / m, 1e-300);
  }
  if (h.mu0 > h.mu1) std::swap(h.mu0, h.mu1), std::swap(h.a01, h.a10);
  return h;
}

// A telegraph inside the wander: a share f of the Gauss-Markov wander's variance var_g of noise model g is
// a symmetric random telegraph (levels -+ sqrt(f var_g), switching with probability a = (1 - phi) / 2 per
// bin, so that its autocorrelation (1 - 2a)^k is the wander's phi^k), the rest, (1 - f) var_g, stays
// Gauss-Markov; white noise and walk as in g. Every f has g's autocovariance, so the
// likelihood ratio against f = 0 (which is g) sees only what second-order tests cannot: two values and
// jumps between them. Log-likelihood of v (mean removed: the telegraph's centre and the walk's start at 0;
// conditional on the first bin, as NoiseModel::NegLogLik, and without its 0.5 ln(2 pi) terms) by the
// switching Kalman filter of Kim (1994): a filtered state per telegraph state, the four branches
// (previous state, state) collapsed to two by their weights. The branches share the Kalman covariance of
// the Gaussian part (the collapsed means' spread is left out), so the filter's gains are those of
// NoiseModel::Prepare; exact at f = 0 (all branches equal). (With a diffuse level the branches' levels
// differ by the telegraph's step from the first bin on, which that shared covariance cannot carry.)
double TelegraphInWanderLogLik(const VectorXd& v, const NoiseModel& g, double f) {
  const int m = static_cast<int>(v.size());
  NoiseModel gp = g;
  gp.var_g = (1 - f) * g.var_g;
  gp.known_level = true;
  gp.Prepare(m);
  const double half = std::sqrt(f * g.var_g), a = 0.5 * (1 - g.phi);
  const double mu[2] = {-half, half}, trans[2][2] = {{1 - a, a}, {a, 1 - a}};
  double prob[2] = {0.5, 0.5};
  // Each state (wander, level) as two scalars: the sanitizer build does not inline Eigen's 2-vectors.
  struct State {
    double x = 0, b = 0;
  };
  State state[2];
  double ll = 0;
  for (int k = 0; k < m; ++k) {
    State pred[2], upd[2][2];
    double arg[2][2], lo = std::numeric_limits<double>::infinity();
    const double g0 = gp.gain[k](0), g1 = gp.gain[k](1);
    for (int j = 0; j < 2; ++j) {
      pred[j] = state[j];
      if (k > 0) pred[j].x *= g.phi;
      for (int s = 0; s < 2; ++s) {
        const double e = v(k) - mu[s] - (pred[j].x + pred[j].b);
        arg[j][s] = 0.5 * e * e * gp.inv_sqrt_s[k] * gp.inv_sqrt_s[k];
        upd[j][s] = {pred[j].x + g0 * e, pred[j].b + g1 * e};
        lo = std::min(lo, arg[j][s]);
      }
    }
    double w[2][2], total = 0;
    for (int j = 0; j < 2; ++j) {
      for (int s = 0; s < 2; ++s) {
        w[j][s] = prob[j] * (k > 0 ? trans[j][s] : static_cast<double>(j == s)) * std::exp(lo - arg[j][s]);
        total += w[j][s];
      }
    }
    if (!(total > 0)) return -std::numeric_limits<double>::infinity();
    if (k > 0) ll += std::log(total) - lo + std::log(gp.inv_sqrt_s[k]);
    for (int s = 0; s < 2; ++s) {
      const double ps = w[0][s] + w[1][s];
      prob[s] = ps / total;
      state[s] = ps > 0 ? State{(w[0][s] * upd[0][s].x + w[1][s] * upd[1][s].x) / ps,
                                (w[0][s] * upd[0][s].b + w[1][s] * upd[1][s].b) / ps}
                        : upd[0][s];
    }
  }
  return ll;
}

// The statistic of JumpsTest: max over f in [0, 1] of TelegraphInWanderLogLik(f) - (its value at f = 0),
// a grid of f = 0.2 ... 1 refined by golden section around the best point. *share: the f of the maximum.
double TelegraphInWanderLlr(const VectorXd& v, const NoiseModel& g, double* share = nullptr) {
  const double l0 = TelegraphInWanderLogLik(v, g, 0);
  double best = 0, best_f = 0;
  auto at = [&](double f) {
    const double l = TelegraphInWanderLogLik(v, g, f) - l0;
    if (l > best + 1e-9) best = l, best_f = f;  // rounding at f near 0 is no share
    return l;
  };
  for (int i = 1; i <= 5; ++i) at(0.2 * i);
  GoldenSectionMax(at, std::max(0.0, best_f - 0.2), std::min(1.0, best_f + 0.2), 8);  // `at` keeps the best
  if (share) *share = best_f;
  return best;
}

// The bootstrap of JumpsTest on one log: p-values of the level split (p_split) and of the test's
// statistic (p_llr) from replicates of the noise model g, with Besag & Clifford's stopping.
struct JumpsBootstrap {
  double p_split = 1, p_llr = 1;
};

JumpsBootstrap BootstrapJumps(const NoiseModel& g, int m, int r, const LevelSplit& obs, double llr_obs) {
  Rng rng(0x5eed0000ULL + static_cast<uint64_t>(r));
  const double sd_w = std::sqrt(g.var_w), sd_g = std::sqrt(g.var_g), sd_x = std::sqrt(g.var_g * (1 - g.phi * g.phi));
  const double sd_rw = std::sqrt(g.q_rw);
  constexpr int kReplicates = 4999, kExceed = 10;
  int exceed_split = 0, done_split = 0, exceed_llr = 0, done_llr = 0;
  auto running = [&](int exceed, int done) { return done < kReplicates && exceed < kExceed; };
  VectorXd z(m);
  while (running(exceed_llr, done_llr)) {
    double x = sd_g * rng.Normal(), walk = 0;
    for (int i = 0; i < m; ++i) {
      if (i > 0) x = g.phi * x + sd_x * rng.Normal(), walk += sd_rw * rng.Normal();
      z(i) = x + walk + sd_w * rng.Normal();
    }
    z.array() -= z.mean();
    if (running(exceed_split, done_split)) exceed_split += SplitLevels(z).ratio <= obs.ratio, ++done_split;
    exceed_llr += !(TelegraphInWanderLlr(z, g) < llr_obs), ++done_llr;  // a NaN replicate counts against
  }
  auto p_of = [](int exceed, int done) {
    return exceed >= kExceed ? exceed / static_cast<double>(done) : (exceed + 1.0) / (done + 1.0);
  };
  return {p_of(exceed_split, done_split), p_of(exceed_llr, done_llr)};
}

}  // namespace

// Jumps of the level between a few values. A level that switches between two values (a random
// telegraph bias, e.g. a light source hopping between modes) has to second order the autocovariance
// of a Gauss-Markov wander, so the tests above, on data whitened with that wander, miss it; what tells
// them apart is that its levels take two values and change at once. Statistic: TelegraphInWanderLlr,
// the log-likelihood ratio of a telegraph carrying a share of the wander (same autocovariance) against
// the log's maximum-likelihood white + Gauss-Markov noise model (and walk, when the walk is the cause):
// nested, so that on the noise model's own replicates it stays near 0 (a two-state HMM in white noise
// against the wander, the statistic until then, fitted a large wander's replicates too: a null spread of
// 3-29 nats; docs/discrepancy.md). Its null distribution is simulated (parametric bootstrap) from that
// noise model, with the sequential stopping of Besag & Clifford (1991): stop at 10 replicates at least as
// large, else after 4999 (p >= 2e-4; a clean log stops after a few dozen); Bonferroni over logs. Also
// reported: the level split of SplitLevels (the within-group share of the variance of the levels of binary
// segmentation's pieces, with its p-value on the same replicates), the switches between its two groups of
// levels and their times, and the two-state HMM's levels and mean dwell (FitTelegraphHmm). Returns the
// smallest p over logs.
double JumpsTest(const Design& d, const std::vector<NoiseModel>& nm, const VectorXd& e, const GyroDiscoverOptions& o,
                 GyroResidual* res) {
  const int l = static_cast<int>(d.bins.size());
  double jump_p = 1;
  for (int r = 0; r < l; ++r) {
    const LogBins& b = d.bins[r];
    const int m = static_cast<int>(b.t_s.size());
    if (m < 100) continue;
    VectorXd v = e.segment(d.offset[r], m);
    v.array() -= v.mean();
    const LevelSplit obs = SplitLevels(v);
    if (obs.level.empty()) continue;
    const NoiseMle f0 = FitNoiseMle(v, b.bin_s, o.wander_tau_max_s, nm[r], nm[r].q_rw > 0);
    const NoiseModel& g = f0.model;
    double share = 0;
    const double llr_obs = TelegraphInWanderLlr(v, g, &share);
    if (!std::isfinite(llr_obs)) continue;  // a degenerate fit is no evidence (no replicate exceeds a NaN)
    const JumpsBootstrap boot = BootstrapJumps(g, m, r, obs, llr_obs);
    if (!(boot.p_llr < jump_p || res->jumps == 0)) continue;
    jump_p = boot.p_llr;
    const TelegraphHmm hmm = FitTelegraphHmm(v, obs);
    res->levels_within_ratio = obs.ratio;
    res->levels_within_p = boot.p_split;
    res->jump_size_dph = obs.high - obs.low;
    res->telegraph_llr = llr_obs;
    res->telegraph_share = share;
    res->telegraph_p = boot.p_llr;
    res->telegraph_levels_dph = hmm.mu1 - hmm.mu0;
    res->telegraph_dwell_s = b.bin_s * 2 / (hmm.a01 + hmm.a10);
    res->jumps = 0;
    res->jump_times_s.clear();
    for (size_t s = 1; s < obs.level.size(); ++s) {
      if ((obs.level[s] > obs.threshold) != (obs.level[s - 1] > obs.threshold)) {
        ++res->jumps;
        const int c = obs.cuts[s];
        res->jump_times_s.push_back(0.5 * (b.t_s[c - 1] + b.t_s[c]));
      }
    }
  }
  return jump_p;
}

}  // namespace ssiu::discover_internal
