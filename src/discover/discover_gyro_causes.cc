// The candidate causes of `ssiu discover gyro` and their fits: the scans that locate a step or a sinusoid,
// the random-walk test, each candidate's Wald test and BIC, and its fit judged on held-out blocks.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "calibration/allan.h"
#include "core/types.h"
#include "discover/discover_gyro_internal.h"

namespace ssiu::discover_internal {

// Bin means of sin/cos(2 pi fr t) over a bin of width `bin`: the instantaneous value times
// sinc(pi fr bin), so that the amplitude is not biased low near the scan's top frequency.
void BinSinusoid(const LogBins& b, double fr, VectorXd* sn, VectorXd* cs) {
  const int m = static_cast<int>(b.t_s.size());
  const double x = kPi * fr * b.bin_s, att = x > 1e-9 ? std::sin(x) / x : 1.0;
  sn->resize(m), cs->resize(m);
  for (int k = 0; k < m; ++k) {
    (*sn)(k) = att * std::sin(2 * kPi * fr * b.t_s[k]);
    (*cs)(k) = att * std::cos(2 * kPi * fr * b.t_s[k]);
  }
}

// Golden-section search for a maximum of fn on [lo, hi], iters steps; returns {x, fn(x)} of the better of
// the last two points.
std::pair<double, double> GoldenSectionMax(const std::function<double(double)>& fn, double lo, double hi, int iters) {
  const double gr = 0.5 * (std::sqrt(5.0) - 1);
  double x1 = hi - gr * (hi - lo), x2 = lo + gr * (hi - lo), f1 = fn(x1), f2 = fn(x2);
  for (int it = 0; it < iters; ++it) {
    if (f1 > f2) {
      hi = x2, x2 = x1, f2 = f1, x1 = hi - gr * (hi - lo), f1 = fn(x1);
    } else {
      lo = x1, x1 = x2, f1 = f2, x2 = lo + gr * (hi - lo), f2 = fn(x2);
    }
  }
  return f1 > f2 ? std::make_pair(x1, f1) : std::make_pair(x2, f2);
}

// GLS periodogram of one log: the chi^2 (2 dof, divided by `norm`) of a sinusoid against whitened
// residual rr (whitened bias column cw projected out), frequencies f_lo..f_hi in steps of a quarter
// of 1/duration, the best refined by golden section. Returns {frequency, chi^2}.
std::pair<double, double> ScanSinusoid(const LogBins& b, const NoiseModel& noise, const VectorXd& cw,
                                       const VectorXd& rr, double norm, double f_lo, double f_hi) {
  const int m = static_cast<int>(b.t_s.size());
  const double dur = b.t_s.back() - b.t_s.front() + b.bin_s;
  auto stat = [&](double fr) {
    VectorXd sn, cs;
    BinSinusoid(b, fr, &sn, &cs);
    MatrixXd a(m, 2);
    const double* in[2] = {sn.data(), cs.data()};
    double* out[2] = {a.col(0).data(), a.col(1).data()};
    noise.WhitenSeries(in, out, 2, m);
    for (int j = 0; j < 2; ++j) a.col(j) -= (cw.dot(a.col(j)) / cw.squaredNorm()) * cw;
    const Eigen::Matrix2d g = a.transpose() * a;
    const Eigen::Vector2d p = a.transpose() * rr;
    if (!(g.determinant() > 1e-12 * g.trace() * g.trace())) return 0.0;
    return p.dot(g.ldlt().solve(p)) / norm;
  };
  const double df = 0.25 / dur;
  double f_best = 0, w_best = 0;
  for (double fr = f_lo; fr <= f_hi; fr += df) {
    const double w = stat(fr);
    if (w > w_best) w_best = w, f_best = fr;
  }
  if (w_best <= 0) return {0.0, 0.0};
  const auto [f_gold, w_gold] = GoldenSectionMax(stat, std::max(f_lo, f_best - df), std::min(f_hi, f_best + df), 30);
  if (w_gold > w_best) w_best = w_gold, f_best = f_gold;
  return {f_best, w_best};
}

// Candidates of one cause with different models (magnetic_field: the azimuth harmonic, the logged
// field) are told apart by cause/model.
std::string Key(const GyroCandidate& c) { return c.model.empty() ? c.cause : c.cause + "/" + c.model; }

// Step scan: a step in one log's bias at a bin boundary (5 %..95 % of the log), on the base model's
// whitened residual base_res (bias columns bw), statistic scaled by sigma2_f = sigma^2 x inflation.
void ScanStep(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& bw, const VectorXd& base_res,
              double sigma2_f, StepScan* sc) {
  const int l = static_cast<int>(d.bins.size());
  sc->best_w = 0;
  sc->positions = 0;
  sc->profile.clear();
  for (int r = 0; r < l; ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    const VectorXd cw = bw.col(r).segment(d.offset[r], m);
    const VectorXd rr = base_res.segment(d.offset[r], m);
    // The whitened steps four positions at a time, each from its first position on (zero before).
    const int j_lo = std::max(1, m / 20), j_hi = m - m / 20;
    MatrixXd steps(m, 4), steps_w(m, 4);
    VectorXd prev;  // the last position's whitened step (empty at the log's start)
    for (int j = j_lo; j < j_hi; ++j) {
      const int c = (j - j_lo) % 4;
      if (c == 0) {
        const int n = std::min(4, j_hi - j);
        const double* in[4];
        double* out[4];
        for (int i = 0; i < n; ++i) {
          steps.col(i).head(j + i).setZero();
          steps.col(i).tail(m - j - i).setOnes();
          steps_w.col(i).head(j).setZero();
          in[i] = steps.col(i).data(), out[i] = steps_w.col(i).data();
        }
        nm[r].WhitenSeries(in, out, n, m, j);
      }
      VectorXd sw = steps_w.col(c);
      sw -= (cw.dot(sw) / cw.squaredNorm()) * cw;
      const double ss = sw.squaredNorm();
      if (ss <= 0) {
        prev.resize(0);
        continue;
      }
      ++sc->positions;
      const double proj = rr.dot(sw);
      const double w = proj * proj / ss / sigma2_f;
      const double rho = prev.size() == m ? prev.dot(sw) / std::sqrt(prev.squaredNorm() * ss) : StepPoint::kNoNeighbour;
      sc->profile.push_back({r, 0.5 * (d.bins[r].t_s[j - 1] + d.bins[r].t_s[j]), w, rho});
      prev.swap(sw);  // sw is not used again: its storage becomes the next position's neighbour
      if (w > sc->best_w) {
        sc->best_w = w;
        sc->best_step = VectorXd::Zero(d.n);
        sc->best_step.segment(d.offset[r] + j, m - j).setOnes();
        sc->best_step_t = 0.5 * (d.bins[r].t_s[j - 1] + d.bins[r].t_s[j]);
        sc->best_step_log = r;
      }
    }
  }
}

// The tail of the largest chi^2_1 of a scan whose neighbouring positions j, j+1 are correlated (rho_j), with b^2 = w.
// Each position after a log's first adds the chance that the statistic first crosses b there: the smaller of
// - James, James & Siegmund's (1987) approximation for the change-point statistic, with the neighbours'
//   distance in the time scale where the standardized step is an Ornstein-Uhlenbeck process (correlation
//   exp(-du / 2), so du = -2 ln rho): b phi(b) du nu(b sqrt(du)), nu the overshoot correction for a process
//   seen at discrete points (the closed-form approximation of Siegmund & Yakir 2007, "The Statistics of Gene
//   Mapping");
// - the Hunter-Worsley bound's term (Worsley 1982, Biometrika 69), P(|Z_j| < b <= |Z_j+1|) <= 4 T(b, sqrt((1 -
//   rho) / (1 + rho))), Owen's T (Owen 1956): it caps the first where the neighbours decorrelate (a wander in
//   the noise model), and both stay below the Bonferroni count's P(|Z| >= b).
// On the static logs the neighbouring steps are nearly one regressor (rho 0.97-0.998), and the count over
// their ~900 positions overstated the tail about 16 times at chi^2 18. Relative to phi(b), so as not to underflow.
double StepScanLogP(const std::vector<StepPoint>& profile, double w) {
  if (profile.empty() || !(w > 0)) return 0.0;
  const double b = std::sqrt(w), log_phi = -0.5 * w - 0.5 * std::log(2 * kPi);
  const auto phi = [](double x) { return std::exp(-0.5 * x * x) / std::sqrt(2 * kPi); };
  const auto cdf = [](double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); };
  // Mills ratio Q(b) / phi(b); beyond b = 30 its asymptotic series (relative error below 1e-8).
  const double mills = b < 30 ? 0.5 * std::erfc(b / std::sqrt(2.0)) / std::exp(log_phi)
                              : (1 - 1 / w + 3 / (w * w) - 15 / (w * w * w)) / b;
  // T(b, a) / phi(b) = (2 pi)^-1/2 int_0^a exp(-b^2 x^2 / 2) / (1 + x^2) dx, Simpson's rule over [0, min(a, 9 / b)].
  const auto owens_t_over_phi = [&](double a) {
    const int n = 64;
    const double h = std::min(a, 9 / b) / n;
    double sum = 0;
    for (int k = 0; k <= n; ++k) {
      const double x = k * h, f = std::exp(-0.5 * w * x * x) / (1 + x * x);
      sum += (k == 0 || k == n ? 1 : (k % 2 ? 4 : 2)) * f;
    }
    return sum * h / 3 / std::sqrt(2 * kPi);
  };
  const auto nu = [&](double x) {
    return x < 1e-6 ? 1.0 : (2 / x) * (cdf(x / 2) - 0.5) / ((x / 2) * cdf(x / 2) + phi(x / 2));
  };
  double total = 0;  // the tail / phi(b)
  for (const StepPoint& p : profile) {
    if (p.rho_prev == StepPoint::kNoNeighbour) {
      total += 2 * mills;
      continue;
    }
    const double rho = std::clamp(p.rho_prev, -1.0, 1.0);
    double term = std::min(2 * mills, 4 * owens_t_over_phi(std::sqrt((1 - rho) / (1 + rho + 1e-300))));
    if (rho > 0) {
      const double du = -2 * std::log(rho);
      term = std::min(term, b * du * nu(b * std::sqrt(du)));
    }
    total += term;
  }
  return std::min(0.0, log_phi + std::log(total));
}

// Periodic scan: a sinusoid in one log's drift, periods from 4 bins to duration / min_cycles
// (the GLS periodogram, frequency step 1/4 of the Fourier spacing, refined by golden section);
// the number of independent frequencies (range x duration) is the Bonferroni count.
void ScanPeriodic(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& bw, const VectorXd& base_res,
                  const GyroDiscoverOptions& o, int pass, double sigma2_f, PeriodicScan* sc) {
  const int l = static_cast<int>(d.bins.size());
  sc->best_pw = 0;
  sc->positions = 0;
  const VectorXd level_res = pass == 0 ? LevelResidual(d) : VectorXd();
  for (int r = 0; r < l; ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    const double dur = d.bins[r].t_s.back() - d.bins[r].t_s.front() + d.bins[r].bin_s;
    const double f_lo = o.periodic_min_cycles / dur, f_hi = 0.25 / d.bins[r].bin_s;
    if (m < 24 || f_hi <= f_lo) continue;
    sc->positions += (f_hi - f_lo) * dur;
    // First pass: the plain periodogram of the base residual. The noise model of that pass was
    // fitted with the sinusoid still in the residual: its wander would whiten the sinusoid away.
    NoiseModel white;
    white.Prepare(m);
    const NoiseModel& noise = pass == 0 ? white : nm[r];
    VectorXd cw = bw.col(r).segment(d.offset[r], m), rr = base_res.segment(d.offset[r], m);
    if (pass == 0) {
      cw.setOnes();
      rr = level_res.segment(d.offset[r], m);
    }
    const auto [f_best, w_best] = ScanSinusoid(d.bins[r], noise, cw, rr, sigma2_f, f_lo, f_hi);
    if (w_best > sc->best_pw) {
      sc->best_pw = w_best;
      sc->best_freq = f_best;
      sc->best_periodic_log = r;
      VectorXd sn, cs;
      BinSinusoid(d.bins[r], f_best, &sn, &cs);
      sc->best_sin = VectorXd::Zero(d.n), sc->best_cos = VectorXd::Zero(d.n);
      sc->best_sin.segment(d.offset[r], m) = sn;
      sc->best_cos.segment(d.offset[r], m) = cs;
    }
  }
}

WalkTest TestRandomWalk(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm,
                        const std::vector<int>& walk_logs, double alpha_each, double n_eff) {
  WalkTest w;
  w.nm_walk = nm;
  GyroCandidate& c = w.candidate;
  c.cause = "rate_random_walk";
  c.dof = 1;
  c.applicable = !walk_logs.empty();
  // On the base-model residuals: the slow regressors of the full model would absorb most of a
  // walk. A deterministic cause then shows here too; it is sorted out by the BIC below.
  double p_min = 1;
  const VectorXd level_res = LevelResidual(d);
  for (int r : walk_logs) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    const VectorXd v = level_res.segment(d.offset[r], m);
    const NoiseMle h0 = FitNoiseMle(v, d.bins[r].bin_s, o.wander_tau_max_s, nm[r], false);
    const NoiseMle h1 = FitWalkMle(v, d.bins[r].bin_s, o.wander_tau_max_s, h0.model);
    const double lr = std::max(0.0, 2 * (h0.nll - h1.nll));
    w.nll += h1.nll;
    const double p = std::min(1.0, walk_logs.size() * 0.5 * ChiSquaredSurvival(lr, 1));
    w.nm_walk[r] = h1.model;
    w.nm_walk[r].diffuse_level = false;
    w.nm_walk[r].Prepare(m);
    if (p < p_min || r == walk_logs.front()) {
      p_min = p;
      c.statistic = lr;
      w.lnq_sigma = h1.ln_q_sigma;
      w.log = r;
    }
  }
  if (c.applicable) {
    c.p_value = p_min;
    c.significant = p_min < alpha_each;
    c.delta_bic = c.statistic - std::log(n_eff);
  }
  return w;
}

// A candidate's usable columns: none when a required one is not usable.
std::vector<int> SpecColumns(const CandidateSpec& sp, const std::vector<bool>& usable) {
  std::vector<int> cols;
  for (int c : sp.required) {
    if (!usable[c]) return cols;
  }
  for (int c : sp.cols) {
    if (usable[c]) cols.push_back(c);
  }
  return cols;
}

ScoreNorm MakeScoreNorm(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& noise,
                        const MatrixXd& x_full) {
  ScoreNorm sn;
  sn.y_w = WhitenRows(d, noise, d.y);
  const MatrixXd xf_w = WhitenRows(d, noise, x_full);
  const LsFit fl = SolveLs(xf_w, sn.y_w);
  sn.s2 = fl.rss / std::max(1, d.n - static_cast<int>(x_full.cols()));
  sn.infl = VarianceInflation(d, sn.y_w - xf_w * fl.beta, o.max_noise_lag);
  sn.base_rss = SolveLs(WhitenRows(d, noise, d.base), sn.y_w).rss;
  return sn;
}

// 3. Every deterministic candidate (specs) and the located step and sinusoid against the base model, with
// GLS under the per-log noise models `noise` and the inflation of the full model's (x_full) whitened
// residuals; their fits go to *fits, the located ones' ln(positions scanned) to *position_cost.
std::vector<GyroCandidate> TestCandidates(const Design& d, const GyroDiscoverOptions& o,
                                          const std::vector<NoiseModel>& noise, const MatrixXd& x_full,
                                          const std::vector<CandidateSpec>& specs, const std::vector<bool>& usable,
                                          double alpha_each, const StepScan& step_scan,
                                          const PeriodicScan& periodic_scan, std::map<std::string, Fitted>* fits,
                                          std::map<std::string, double>* position_cost) {
  const bool step_ok = step_scan.best_step.size() == d.n, periodic_ok = periodic_scan.best_sin.size() == d.n;
  std::vector<GyroCandidate> out;
  const ScoreNorm sn = MakeScoreNorm(d, o, noise, x_full);
  const double infl = sn.infl;
  const double n_eff = d.n / infl;
  auto score = [&](GyroCandidate* c, const MatrixXd& x, const std::vector<int>& cols, double extra_cost) {
    const LsFit g = SolveLs(WhitenRows(d, noise, x), sn.y_w);
    c->statistic = std::max(0.0, (sn.base_rss - g.rss) / (sn.s2 * infl));
    c->delta_bic = d.n * std::log(sn.base_rss / g.rss) / infl - c->dof * std::log(n_eff) - extra_cost;
    (*fits)[Key(*c)] = {g, x, cols, infl};
  };
  for (const auto& sp : specs) {
    GyroCandidate c;
    c.cause = sp.cause;
    c.model = sp.model;
    const std::vector<int> cols = SpecColumns(sp, usable);
    c.dof = static_cast<int>(cols.size());
    c.applicable = !cols.empty();
    if (c.applicable) {
      // thermal_lag's time constant was located by a scan: Bonferroni over its positions, which cost in the BIC.
      const double npos = sp.cause == "thermal_lag" ? std::max(1, d.lag_positions) : 1;
      if (npos > 1) (*position_cost)[sp.cause] = std::log(npos);
      score(&c, Assemble(d, cols, {}), cols, npos > 1 ? std::log(npos) : 0.0);
      c.p_value = std::min(1.0, npos * ChiSquaredSurvival(c.statistic, c.dof));
      c.significant = c.p_value < alpha_each;
    }
    out.push_back(c);
  }
  // The located ones: p-values corrected for the positions tried (the step's by StepScanLogP, the sinusoid's
  // Bonferroni over its independent frequencies); ln of the positions costs in the BIC.
  auto located = [&](const std::string& cause, bool ok, const std::vector<VectorXd>& cols, double npos) {
    GyroCandidate c;
    c.cause = cause;
    c.dof = static_cast<int>(cols.size());
    c.applicable = ok;
    if (ok) {
      (*position_cost)[cause] = std::log(std::max(npos, 1.0));
      score(&c, Assemble(d, {}, cols), {}, (*position_cost)[cause]);
      c.p_value = cause == "bias_step" ? std::exp(StepScanLogP(step_scan.profile, c.statistic))
                                       : std::min(1.0, std::max(npos, 1.0) * ChiSquaredSurvival(c.statistic, c.dof));
      c.significant = c.p_value < alpha_each;
    }
    out.push_back(c);
  };
  located("bias_step", step_ok, {step_scan.best_step}, step_scan.positions);
  located("periodic_drift", periodic_ok, {periodic_scan.best_sin, periodic_scan.best_cos}, periodic_scan.positions);
  return out;
}

// 4. A significant candidate's BIC of the exact likelihood (noise model refitted by maximum likelihood
// on each log's residual), position_cost: ln(positions scanned) of the located candidates.
// The BIC of the exact likelihood of the deterministic model x (base + dof terms): GLS under nm, each log's
// noise refitted by maximum likelihood on its residual; cost: ln(positions scanned) of its located terms.
double FittedBic(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm, const MatrixXd& x,
                 int dof, double cost) {
  const int l = static_cast<int>(d.bins.size());
  const LsFit g = SolveLs(WhitenRows(d, nm, x), WhitenRows(d, nm, d.y));
  const VectorXd e = d.y - x * g.beta;
  double bic = 0;
  for (int r = 0; r < l; ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    bic += 2 * FitNoiseMle(e.segment(d.offset[r], m), d.bins[r].bin_s, o.wander_tau_max_s, nm[r], false).nll;
  }
  return bic + (3.0 * l + dof) * std::log(static_cast<double>(d.n)) + 2 * cost;
}

double CandidateBic(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm,
                    const GyroCandidate& c, const std::vector<int>& walk_logs, double walk_nll,
                    std::map<std::string, Fitted>* fits, const std::map<std::string, double>& position_cost) {
  const int l = static_cast<int>(d.bins.size());
  double bic = 0;
  if (c.cause == "rate_random_walk") {
    // The short logs keep their base noise model: only the long ones carry the walk.
    bic = 2 * walk_nll + 4.0 * walk_logs.size() * std::log(static_cast<double>(d.n));
    const VectorXd level_res = LevelResidual(d);
    for (int r = 0; r < l; ++r) {
      if (std::find(walk_logs.begin(), walk_logs.end(), r) != walk_logs.end()) continue;
      const int m = static_cast<int>(d.bins[r].t_s.size());
      const VectorXd v = level_res.segment(d.offset[r], m);
      bic += 2 * FitNoiseMle(v, d.bins[r].bin_s, o.wander_tau_max_s, nm[r], false).nll + 3.0 * std::log(double(d.n));
    }
  } else {
    bic = FittedBic(d, o, nm, (*fits)[Key(c)].x, c.dof, position_cost.count(c.cause) ? position_cost.at(c.cause) : 0.0);
  }
  return bic;
}

// rate_random_walk's parameter and held-out gain (the walk q_rw per bin, of log walk_log).
void EvaluateWalk(const Design& d, const GyroDiscoverOptions& o, const std::vector<int>& walk_logs,
                  const std::vector<double>& log_var, double q, int walk_log, double walk_lnq_sigma, Evaluation* ev) {
  auto& par = ev->parameters;
  auto& sig = ev->sigmas;
  // K from the walk's variance per bin: q = K^2 bin (K in dph/sqrt(s)).
  const double bin = d.bins[walk_log].bin_s;
  const double k_dph_sqrt_h = std::sqrt(q / bin) * 60.0;
  par["K_dph_per_sqrt_h"] = k_dph_sqrt_h;
  sig["K_dph_per_sqrt_h"] = 0.5 * k_dph_sqrt_h * walk_lnq_sigma;
  // Held-out one-step prediction of the second half's bins: constant bias (base) vs an
  // exponentially smoothed level with its factor tuned on the first half (local-level model).
  double best_ratio = -1;
  ev->cv.z = -std::numeric_limits<double>::infinity();
  const VectorXd level_res = LevelResidual(d);
  for (int rr : walk_logs) {
    const int mm = static_cast<int>(d.bins[rr].t_s.size());
    const VectorXd z = level_res.segment(d.offset[rr], mm);
    const int half = mm / 2;
    // Squared one-step errors from `from` to `to` with smoothing factor a (0: constant level).
    auto one_step = [&](double a, int from, int to, double level, std::vector<double>* e2) {
      double ss = 0;
      for (int i = from; i < to; ++i) {
        const double e = z(i) - level;
        ss += e * e;
        if (e2) e2->push_back(e * e);
        level += a * e;
      }
      return ss;
    };
    double best_a = 0, best_ss = std::numeric_limits<double>::infinity();
    for (double a = 0.002; a <= 0.5; a *= 1.25) {
      const double ss = one_step(a, 1, half, z(0), nullptr);
      if (ss < best_ss) best_ss = ss, best_a = a;
    }
    const double mean_first = z.head(half).mean();
    double level = z(0);
    for (int i = 1; i < half; ++i) level += best_a * (z(i) - level);
    std::vector<double> eb, ea;
    const double sb = one_step(0.0, half, mm, mean_first, &eb), sa = one_step(best_a, half, mm, level, &ea);
    const int nblk = o.cv_blocks / 2;
    std::vector<double> blk(nblk, 0.0);
    for (size_t i = 0; i < eb.size(); ++i) blk[i * nblk / eb.size()] += (eb[i] - ea[i]) / log_var[rr];
    ev->cv.z = std::max(ev->cv.z, BlockZ(blk));
    ev->cv.z_blocks = ev->cv.z;  // already the blocks' own scatter
    if (sb / sa > best_ratio) {  // the log where the level model predicts best carries the figure
      best_ratio = sb / sa;
      ev->cv.rms_before = std::sqrt(sb / (mm - half));
      ev->cv.rms_after = std::sqrt(sa / (mm - half));
    }
  }
}

// A fitted candidate's parameters (GLS, sigma scaled by the residual variance and the inflation) and
// its held-out gain; the located step's and sinusoid's from their scans.
void EvaluateFitted(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm, const Fitted& fit,
                    const std::string& cause, const std::vector<double>& scale, const StepScan& step_scan,
                    const PeriodicScan& periodic_scan, Evaluation* ev) {
  const int l = static_cast<int>(d.base.cols());  // the cause's coefficients follow the base model's
  auto& par = ev->parameters;
  auto& sig = ev->sigmas;
  const double best_step_t = step_scan.best_step_t, best_w = step_scan.best_w, best_freq = periodic_scan.best_freq;
  const int best_step_log = step_scan.best_step_log, best_periodic_log = periodic_scan.best_periodic_log;
  const std::vector<StepPoint>& step_profile = step_scan.profile;
  const VectorXd &best_sin = periodic_scan.best_sin, &best_cos = periodic_scan.best_cos;
  const LsFit& g = fit.gls;
  const int dof_res = std::max(1, d.n - static_cast<int>(fit.x.cols()));
  const double s2 = g.rss / dof_res * fit.inflation;
  auto pos = [&](int col) {
    return l + static_cast<int>(std::find(fit.cols.begin(), fit.cols.end(), col) - fit.cols.begin());
  };
  auto has = [&](int col) { return std::find(fit.cols.begin(), fit.cols.end(), col) != fit.cols.end(); };
  auto est = [&](int col, double unscale, const std::string& name) {
    const int j = pos(col);
    par[name] = g.beta(j) / unscale;
    sig[name] = std::sqrt(g.cov_unscaled(j, j) * s2) / unscale;
  };
  // A harmonic e_s sin x + e_c cos x = S sin(x + phi) from coefficient rows js, jc.
  // Its covariance from `gc` (for periodic_drift: the fit with the frequency free).
  auto harmonic = [&](int js, int jc, double us, double uc, const LsFit& gc) {
    const double es = g.beta(js) / us, ec = g.beta(jc) / uc;
    Eigen::Matrix2d cov;
    cov << gc.cov_unscaled(js, js) / (us * us), gc.cov_unscaled(js, jc) / (us * uc),
        gc.cov_unscaled(jc, js) / (us * uc), gc.cov_unscaled(jc, jc) / (uc * uc);
    cov *= s2;
    const double amp = std::hypot(es, ec);
    const Eigen::Vector2d da(es / amp, ec / amp), dp(-ec / (amp * amp), es / (amp * amp));
    par["amplitude_dph"] = amp;
    sig["amplitude_dph"] = std::sqrt(da.dot(cov * da));
    par["phase_deg"] = std::atan2(ec, es) * kRadToDeg;
    sig["phase_deg"] = std::sqrt(dp.dot(cov * dp)) * kRadToDeg;
  };
  // Largest swing of one term against the swing of their sum (over all bins): correlated
  // regressors that cancel each other (absurd coefficients) show as a ratio >> 1.
  auto swing_ratio = [&](const std::vector<std::vector<int>>& groups) {
    VectorXd total = VectorXd::Zero(d.n);
    double worst = 0;
    for (const auto& grp : groups) {
      VectorXd t = VectorXd::Zero(d.n);
      for (int col : grp) {
        if (has(col)) t += d.cols.col(col) * g.beta(pos(col));
      }
      total += t;
      worst = std::max(worst, t.maxCoeff() - t.minCoeff());
    }
    const double range = total.maxCoeff() - total.minCoeff();
    return range > 0 ? worst / range : 1.0;
  };
  if (cause == "temperature") {
    est(kT1, scale[kT1], "K10_dph");
    est(kT2, scale[kT2], "K20_dph");
    par["swing_ratio"] = swing_ratio({{kT1}, {kT2}});
  } else if (cause == "temperature_gradient") {
    est(kG1, scale[kG1], "K01_dph");
  } else if (cause == "thermal_lag") {
    // K per 10 C of the lagged temperature (eq. (1)'s K10 for tau -> 0); tau's sigma from the GLS with the
    // column's derivative in tau added (linearised), as periodic_drift's period.
    est(kLag, scale[kLag], "K_lag_dph");
    MatrixXd xd(d.n, fit.x.cols() + 1);
    xd << fit.x, d.lag_dtau * (g.beta(pos(kLag)) / scale[kLag]);
    const LsFit gd = SolveLs(WhitenRows(d, nm, xd), WhitenRows(d, nm, d.y));
    par["tau_s"] = d.lag_tau_s, sig["tau_s"] = std::sqrt(gd.cov_unscaled(fit.x.cols(), fit.x.cols()) * s2);
    // The lag against none (tau -> 0: the temperature itself), by the likelihood ratio, both with eq. (1)'s
    // K20: a curvature of the drift in T is not a lag (the linearised sigma of tau is a poor guide near 0,
    // where the profile is one-sided).
    MatrixXd x1(d.n, fit.x.cols() + 1), x0;
    x1 << fit.x, d.cols.col(kT2);
    x0 = x1;
    x0.col(pos(kLag)) = d.cols.col(kT1);
    const LsFit g1 = SolveLs(WhitenRows(d, nm, x1), WhitenRows(d, nm, d.y));
    const LsFit g0 = SolveLs(WhitenRows(d, nm, x0), WhitenRows(d, nm, d.y));
    const double s2_1 = g1.rss / std::max(1, d.n - static_cast<int>(x1.cols())) * fit.inflation;
    par["lag_vs_none_chi2"] = std::max(0.0, (g0.rss - g1.rss) / s2_1);
  } else if (cause == "magnetic_field") {
    // f = e_sin sin(psi) + e_cos cos(psi) = S sin(psi + phi); the logged field's sensitivities.
    if (has(kMagSin) && has(kMagCos)) harmonic(pos(kMagSin), pos(kMagCos), scale[kMagSin], scale[kMagCos], g);
    if (has(kBn)) est(kBn, scale[kBn], "sensitivity_bn_dph_per_ut");
    if (has(kBe)) est(kBe, scale[kBe], "sensitivity_be_dph_per_ut");
    if (has(kBh)) est(kBh, scale[kBh], "sensitivity_bh_dph_per_ut");
    par["swing_ratio"] = swing_ratio({{kMagSin, kMagCos}, {kBn}, {kBe}, {kBh}});
  } else if (cause == "misalignment") {
    est(kMis, scale[kMis], "misalignment_arcsec");
  } else if (cause == "scale_factor") {
    est(kScale, scale[kScale], "scale_factor_ppm");
  } else if (cause == "scale_factor_asymmetry") {
    // drift = s ref + a |ref| (ppm): scale factor s + a for positive rates, s - a for negative.
    const int js = pos(kScale), ja = pos(kAbsRef);
    const double us = scale[kScale], ua = scale[kAbsRef];
    const double s = g.beta(js) / us, a = g.beta(ja) / ua;
    const double vs = g.cov_unscaled(js, js) * s2 / (us * us), va = g.cov_unscaled(ja, ja) * s2 / (ua * ua);
    const double csa = g.cov_unscaled(js, ja) * s2 / (us * ua);
    par["scale_factor_ppm"] = s, sig["scale_factor_ppm"] = std::sqrt(vs);
    par["asymmetry_ppm"] = 2 * a, sig["asymmetry_ppm"] = 2 * std::sqrt(va);
    par["scale_factor_positive_ppm"] = s + a,
    sig["scale_factor_positive_ppm"] = std::sqrt(std::max(0.0, vs + va + 2 * csa));
    par["scale_factor_negative_ppm"] = s - a,
    sig["scale_factor_negative_ppm"] = std::sqrt(std::max(0.0, vs + va - 2 * csa));
  } else if (cause == "time_delay") {
    est(kDelay, scale[kDelay], "delay_s");
  } else if (cause == "bias_step") {
    par["step_dph"] = g.beta(l), sig["step_dph"] = std::sqrt(g.cov_unscaled(l, l) * s2);
    // Step time: the positions whose statistic is within 1 of the best (a profile-likelihood
    // interval, Delta chi^2 = 1); half its width, at least one bin.
    double t_lo = best_step_t, t_hi = best_step_t;
    for (const auto& sp : step_profile) {
      if (sp.log == best_step_log && sp.w >= best_w - 1) t_lo = std::min(t_lo, sp.t_s), t_hi = std::max(t_hi, sp.t_s);
    }
    par["step_time_s"] = best_step_t;
    sig["step_time_s"] = std::max(d.bins[best_step_log].bin_s, 0.5 * (t_hi - t_lo));
  } else if (cause == "periodic_drift") {
    // Period sigma: the GLS covariance with the derivative in frequency added (linearised).
    const LogBins& b = d.bins[best_periodic_log];
    VectorXd dcol = VectorXd::Zero(d.n);
    for (size_t k = 0; k < b.t_s.size(); ++k) {
      const int i = d.offset[best_periodic_log] + static_cast<int>(k);
      const double tt = 2 * kPi * b.t_s[k];
      dcol(i) = tt * (g.beta(l) * best_cos(i) - g.beta(l + 1) * best_sin(i));
    }
    MatrixXd xd(d.n, fit.x.cols() + 1);
    xd << fit.x, dcol;
    const LsFit gd = SolveLs(WhitenRows(d, nm, xd), WhitenRows(d, nm, d.y));
    const double sf = std::sqrt(gd.cov_unscaled(fit.x.cols(), fit.x.cols()) * s2);
    harmonic(l, l + 1, 1.0, 1.0, gd);  // phase at t_s = 0: its sigma grows with the frequency's
    par["period_s"] = 1 / best_freq, sig["period_s"] = sf / (best_freq * best_freq);
    par["frequency_hz"] = best_freq, sig["frequency_hz"] = sf;
  }
  ev->cv = CrossValidate(d, nm, fit.x, o.cv_blocks);
}

}  // namespace ssiu::discover_internal
