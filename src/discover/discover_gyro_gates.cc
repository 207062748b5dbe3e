// The gates of one step of `ssiu discover gyro`: the held-out gain, the physical bounds, the rivals a
// candidate must beat (the reference, a shape in time, a logged column, a walk, a pair of causes), and the
// step that runs the candidates through them in BIC order.
#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/distributions/normal.hpp>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "calibration/allan.h"
#include "core/error.h"
#include "discover/discover_gyro_internal.h"

namespace ssiu::discover_internal {

// Significance of a held-out improvement: per-bin differences of squared held-out errors (before -
// after, in units of the log's noise variance) summed per block; z = mean / (sd / sqrt(B)) over the
// B blocks of one log (a paired test: the blocks' spread is the hold-out's own noise, so under the
// null of no effect z is ~N(0, 1), slightly negative since the cause's fitted terms add noise).
double BlockZ(const std::vector<double>& block_sums) {
  const int b = static_cast<int>(block_sums.size());
  if (b < 3) return 0;
  double mean = 0, ss = 0;
  for (double v : block_sums) mean += v / b;
  for (double v : block_sums) ss += (v - mean) * (v - mean);
  const double se = std::sqrt(ss / (b - 1) / b);
  return se > 0 ? mean / se : 0.0;
}

// Cross-validated RMS (bias-only base vs base + columns), fitting on even blocks and scoring on odd
// blocks and vice versa; OLS weighted by each log's noise variance.
// Significance: with p the held-out prediction of the cause (after - before) and e the held-out
// residual of the base, the improvement is D = sum(e^2 - (e - p)^2) = 2 e.p - p.p. If the cause had
// no effect, e would be the log's noise (covariance S from its fitted white + Gauss-Markov model,
// independent of p, which comes from the other blocks): D would have mean -p.p and standard deviation
// 2 sqrt(p' S p). z = (D + p.p) / (2 sqrt(p' S p)) = e.p / sqrt(p' S p) is N(0, 1) under that null.
CvResult CrossValidate(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& x_cause, int blocks) {
  const int l = static_cast<int>(d.bins.size());
  std::vector<int> fold(d.n);
  VectorXd wt(d.n), e_base(d.n), pred(d.n);
  std::vector<double> log_var(l);
  for (int r = 0; r < l; ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    log_var[r] = nm[r].var_w + nm[r].var_g;
    for (int k = 0; k < m; ++k) {
      fold[d.offset[r] + k] = (k * blocks / m) % 2;
      wt(d.offset[r] + k) = 1 / std::sqrt(log_var[r]);
    }
  }
  for (int f = 0; f < 2; ++f) {
    std::vector<int> train, test;
    for (int i = 0; i < d.n; ++i) (fold[i] == f ? train : test).push_back(i);
    auto fit = [&](const MatrixXd& x) {
      MatrixXd xt(train.size(), x.cols());
      VectorXd yt(train.size());
      for (size_t i = 0; i < train.size(); ++i) {
        xt.row(i) = x.row(train[i]) * wt(train[i]);
        yt(i) = d.y(train[i]) * wt(train[i]);
      }
      return SolveLs(xt, yt).beta;
    };
    const VectorXd bb = fit(d.base), ba = fit(x_cause);
    for (int i : test) {
      e_base(i) = d.y(i) - d.base.row(i).dot(bb);
      pred(i) = x_cause.row(i).dot(ba) - d.base.row(i).dot(bb);
    }
  }
  CvResult cv;
  cv.z = -std::numeric_limits<double>::infinity();
  double best_gain = -1;
  for (int r = 0; r < l; ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    const VectorXd e = e_base.segment(d.offset[r], m), p = pred.segment(d.offset[r], m);
    const double ss_before = e.squaredNorm(), ss_after = (e - p).squaredNorm();
    // p' S p with S_ij = var_w delta_ij + var_g phi^|i-j| (AR(1) sum by recursion).
    double psp = (nm[r].var_w + nm[r].var_g) * p.squaredNorm(), s = 0;
    for (int k = 1; k < m; ++k) {
      s = nm[r].phi * (s + p(k - 1));
      psp += 2 * nm[r].var_g * p(k) * s;
    }
    if (psp > 0) cv.z = std::max(cv.z, e.dot(p) / std::sqrt(psp));
    {
      std::vector<double> blk(blocks, 0.0);
      for (int k = 0; k < m; ++k) blk[k * blocks / m] += (e(k) * e(k) - std::pow(e(k) - p(k), 2)) / log_var[r];
      cv.z_blocks = r == 0 ? BlockZ(blk) : std::max(cv.z_blocks, BlockZ(blk));
    }
    // The log where the cause explains most (in units of that log's noise variance) carries the
    // figure: pooling logs of very different noise would dilute it.
    const double g = (ss_before - ss_after) / log_var[r];
    if (g > best_gain || r == 0) {
      best_gain = g;
      cv.rms_before = std::sqrt(ss_before / m);
      cv.rms_after = std::sqrt(ss_after / m);
    }
  }
  if (!std::isfinite(cv.z)) cv.z = 0;
  return cv;
}

bool WiderWarranted(const std::string& nested_cause, double extra_chi2, double wide_chi2, int extra_dof, double alpha) {
  if (nested_cause == "misalignment") return FieldPhaseWarranted(extra_chi2, wide_chi2);
  return ChiSquaredSurvival(extra_chi2, extra_dof) < alpha;
}

namespace {

// Physical bounds (the table of docs/discrepancy.md): empty when cause's parameters par lie within
// them, else the first parameter beyond.
std::string OutOfBounds(const std::string& cause, const std::map<std::string, double>& par) {
  struct Bound {
    const char* cause;
    const char* parameter;
    double max_abs;
  };
  static const Bound kBounds[] = {
      {"temperature", "K10_dph", 5},
      {"temperature", "K20_dph", 5},
      {"temperature", "swing_ratio", 5},
      {"temperature_gradient", "K01_dph", 5},
      {"thermal_lag", "K_lag_dph", 5},
      {"magnetic_field", "amplitude_dph", 2},
      {"magnetic_field", "sensitivity_bn_dph_per_ut", 0.1},
      {"magnetic_field", "sensitivity_be_dph_per_ut", 0.1},
      {"magnetic_field", "sensitivity_bh_dph_per_ut", 0.1},
      {"magnetic_field", "swing_ratio", 5},
      {"misalignment", "misalignment_arcsec", 3600},
      {"scale_factor", "scale_factor_ppm", 1e4},
      {"scale_factor_asymmetry", "scale_factor_ppm", 1e4},
      {"scale_factor_asymmetry", "asymmetry_ppm", 1e4},
      {"time_delay", "delay_s", 0.1},
      {"bias_step", "step_dph", 10},
      {"periodic_drift", "amplitude_dph", 10},
      {"rate_random_walk", "K_dph_per_sqrt_h", 2},
  };
  for (const auto& bd : kBounds) {
    if (cause != bd.cause || !par.count(bd.parameter)) continue;
    const double v = par.at(bd.parameter);
    if (!(std::abs(v) <= bd.max_abs)) {
      return std::string(bd.parameter) + " = " + std::to_string(v) + " beyond " + std::to_string(bd.max_abs);
    }
  }
  return "";
}

// 5. The gates of an evaluated candidate: its held-out gain and verdict; true when it is named.
bool JudgeCandidate(const Evaluation& ev, double z_min, const GyroDiscoverOptions& o, GyroCandidate* c) {
  c->evaluated = true;
  c->gain = ev.cv.rms_after > 0 ? ev.cv.rms_before / ev.cv.rms_after : 1.0;
  c->gain_z = ev.cv.z;
  c->gain_z_blocks = ev.cv.z_blocks;
  if (!ev.out_of_bounds.empty()) {
    c->verdict = "outside bounds: " + ev.out_of_bounds;
  } else if (!(c->gain > 1 && c->gain_z > z_min)) {
    c->verdict = "held-out gain not significant";
  } else if (!(c->gain_z_blocks > o.min_block_z)) {
    // The modelled z rests on the fitted noise; judged by the held-out blocks' own scatter the
    // improvement must show too (a realisation with more slow power than the bounded wander, e.g. a
    // telegraph bias with long dwells, inflates the modelled z of any slow regressor).
    c->verdict = "held-out gain not seen in the blocks";
  } else {
    c->verdict = "named";
  }
  return c->verdict == "named";
}

// A nested candidate replaced by the wider one when WiderWarranted.
GyroCandidate* Upgrade(GyroCandidate* c, std::vector<GyroCandidate>* candidates, double alpha) {
  const std::map<std::string, std::string> wider = {{"misalignment", "magnetic_field"},
                                                    {"scale_factor", "scale_factor_asymmetry"}};
  if (!wider.count(c->cause)) return c;
  GyroCandidate* w = nullptr;
  for (auto& cand : *candidates) {
    if (cand.cause == wider.at(c->cause)) {
      w = &cand;
      break;
    }
  }
  if (!w || !w->applicable || !w->significant || w->dof <= c->dof) return c;
  return WiderWarranted(c->cause, w->statistic - c->statistic, w->statistic, w->dof - c->dof, alpha) ? w : c;
}

// A candidate that a fixed function of the logged reference explains at least as well is not named.
// A drift with the azimuth's second harmonic: on a turntable that turns at a steady pace it is periodic in
// time too (45 deg every 45 min: a 3 h staircase) and periodic_drift's scan finds it; on a static log
// whose reference is Earth rate x cos psi, |ref| holds the same harmonic (|cos psi| = 2/pi + (4/3pi)
// cos 2 psi - ...), and scale_factor_asymmetry fits it with an absurd asymmetry (6110 ppm measured).
// Compared by p-value (the sinusoid's without its scan correction, so the doubt goes to the candidate):
// the reference's functions of `logs` (NonlinearChi2, summed over the logs) against the base model with the
// candidates' normalisation (sigma2_f). The verdict says so and the next candidate is tried; the residual
// test's nonlinearity test finds the harmonic (`unexplained`).
bool FollowsReference(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& bw, const VectorXd& base_res,
                      double sigma2_f, const std::vector<int>& logs, GyroCandidate* c) {
  double chi2 = 0;
  int dof = 0;
  std::string term;
  for (int r : logs) {
    const NonlinearFit nf = NonlinearChi2(d, nm, bw, base_res, r, sigma2_f);
    chi2 += nf.chi2, dof += nf.dof;
    if (nf.dof > 0) term = nf.term;
  }
  if (dof == 0 || LogChi2Survival(chi2, dof) > LogChi2Survival(c->statistic, c->dof)) return false;
  c->evaluated = true;
  c->verdict = "follows the logged reference's " + term + " (chi^2 " + std::to_string(chi2) + ", " +
               std::to_string(dof) + " dof)";
  return true;
}

// A candidate that a deterministic shape in time explains at least as well on the logs where it acts is
// not named: a linear trend (ageing, a rate ramp) was named rate_random_walk, temperature or bias_step, a
// warm-up after switch-on bias_step or temperature_gradient (14 of 16 cases), and with those refused a
// trend was named misalignment (its first harmonic over two turns of the azimuth). The shapes of
// TimeShapeChi2 (the best of the candidate's logs, Bonferroni over them and over the shapes)
// against the base model, compared by p-value with the candidate's (the step's with its scan correction,
// as the shapes' with theirs). The residual test's trend test then finds the shape.
// Two causes together (a temperature with its gradient, a gradient with a bias step) can look like a shape
// that neither explains alone as well: the candidate's p is then the better of its own and pair_log_p
// (its terms together with another significant candidate's, BestPairLogP), so that the pair is not refused
// when it explains the drift better than the shape does.
bool FollowsTimeShape(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& bw, const VectorXd& base_res,
                      double sigma2_f, const std::vector<int>& logs, const std::function<bool(double)>& survives,
                      double pair_log_p, GyroCandidate* c) {
  int tested = 0;
  TimeShapeFit best;
  for (int r : logs) {
    const TimeShapeFit ts = TimeShapeChi2(d, nm, bw, base_res, r, sigma2_f);
    if (ts.fit.dof == 0) continue;
    ++tested;
    if (tested == 1 || ts.log_p < best.log_p) best = ts;
  }
  if (tested == 0) return false;
  const double log_p_shape = std::min(0.0, std::log(static_cast<double>(tested)) + best.log_p);
  if (log_p_shape > std::min(LogCandidateP(*c), pair_log_p) || (survives && survives(best.tau_s))) return false;
  c->evaluated = true;
  c->verdict = "follows a shape in time: " + best.fit.term + " (chi^2 " + std::to_string(best.fit.chi2) + ", " +
               std::to_string(best.fit.dof) + " dof, ln p " + std::to_string(log_p_shape) + ")";
  return true;
}

// A drift that follows a logged column outside the vocabulary's models (not ref, temperature, azimuth or the
// field: a humidity, a heater, a supply voltage) is not a periodic drift, a step or a walk even where one of
// those fits it: a drift following a humidity that cycles every 2-5 h was named periodic_drift 4 of 4 times
// (an independent probe, docs/discrepancy.md). Each such column of the candidate's logs alone
// (FixedColumnsChi2, 1 dof) against the base model; the best, Bonferroni over the columns tested, compared
// by p-value with the candidate's as in FollowsTimeShape. The residual test's column test then names it.
bool FollowsLoggedColumn(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& bw,
                         const VectorXd& base_res, double sigma2_f, const std::vector<int>& logs, GyroCandidate* c) {
  static const std::set<std::string> modelled = {"ref_dph", "temp_c", "azimuth_deg", "bn_ut", "be_ut", "bh_ut"};
  int tested = 0;
  double best_log_p = 0;
  std::string best_name;
  double best_chi2 = 0;
  for (int r : logs) {
    for (const auto& [name, v] : d.bins[r].column_mean) {
      if (modelled.count(name)) continue;
      const NonlinearFit f = FixedColumnsChi2(d, nm, bw, base_res, r, sigma2_f, {{name, v}});
      if (f.dof == 0) continue;
      ++tested;
      const double log_p = LogChi2Survival(f.chi2, f.dof);
      if (best_name.empty() || log_p < best_log_p) best_log_p = log_p, best_name = name, best_chi2 = f.chi2;
    }
  }
  if (tested == 0) return false;
  const double log_p_col = std::min(0.0, std::log(static_cast<double>(tested)) + best_log_p);
  if (log_p_col > LogCandidateP(*c)) return false;
  c->evaluated = true;
  c->verdict = "follows the logged column " + best_name + " (chi^2 " + std::to_string(best_chi2) + ", ln p " +
               std::to_string(log_p_col) + ")";
  return true;
}

// A random walk is not a trend, but its path holds one (for a Brownian path the first Karhunen-Loeve term
// carries 81 % of the variance): a strong walk's P1 alone had chi^2 70-93 against the bounded wander, more
// than the walk's own likelihood ratio (54-59), and 2 of 6 true walks were refused; with P1 and P2 regressed
// out, what is left of a walk is too weak to test at alpha. So the two explanations are compared by their
// exact likelihoods, on each walk log: the base residual with the walk in the noise model (as its test),
// against the residual with the trend (P1, P2) and the shape's warm-up (tau_s > 0) regressed out under the
// bounded wander, with BIC penalties (1 parameter for the walk, one per shape column). The walk is kept
// when it wins on a log.
bool WalkBeatsShape(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm,
                    const std::vector<int>& walk_logs, double tau_s) {
  const VectorXd level_res = LevelResidual(d);
  for (int r : walk_logs) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    MatrixXd x = TrendColumns(d.bins[r]);
    if (tau_s > 0) {
      x.conservativeResize(Eigen::NoChange, 4);
      for (const auto& [fns, tau] : TimeShapes(d.bins[r])) {
        if (tau == tau_s) x.col(3) = Eigen::Map<const VectorXd>(fns.at("exp(-t/tau)").data(), m);
      }
    }
    const VectorXd y = level_res.segment(d.offset[r], m);
    const VectorXd shaped = y - x * SolveLs(x, y).beta;
    const double nll_shape = FitNoiseMle(shaped, d.bins[r].bin_s, o.wander_tau_max_s, nm[r], false).nll;
    VectorXd v = y;
    v.array() -= v.mean();
    const NoiseMle h0 = FitNoiseMle(v, d.bins[r].bin_s, o.wander_tau_max_s, nm[r], false);
    const double nll_walk = FitWalkMle(v, d.bins[r].bin_s, o.wander_tau_max_s, h0.model).nll;
    const double ln_n = std::log(static_cast<double>(m));
    if (nll_walk + 0.5 * ln_n < nll_shape + 0.5 * ln_n * (x.cols() - 1)) return true;
  }
  return false;
}

// The logs where a fitted candidate's columns (beyond the bias) are not all zero.
std::vector<int> CandidateLogs(const Design& d, const Fitted& fit) {
  std::vector<int> out;
  const int l = static_cast<int>(d.base.cols());
  for (int r = 0; r < static_cast<int>(d.bins.size()); ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    if (fit.x.cols() > l && fit.x.block(d.offset[r], l, m, fit.x.cols() - l).cwiseAbs().maxCoeff() > 0)
      out.push_back(r);
  }
  return out;
}

// The logs whose reference functions (LogBins::nonlinear_mean) are the azimuth's harmonic.
std::vector<int> AzimuthLogs(const Design& d) {
  std::vector<int> out;
  for (int r = 0; r < static_cast<int>(d.bins.size()); ++r) {
    if (d.bins[r].nonlinear_mean.count("cos(2 azimuth)")) out.push_back(r);
  }
  return out;
}

// The checks before the gates, in this order: a fixed function of the logged reference (FollowsReference:
// periodic_drift on its log, scale_factor_asymmetry on the azimuth logs), a shape in time (FollowsTimeShape,
// every candidate on `logs`, the logs where it acts; a walk survives when walk_survives says so) and a logged
// column outside the models (FollowsLoggedColumn, the causes with no logged driver). True when one of them
// explains the candidate at least as well (its verdict says which).
bool ExplainedOtherwise(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& bw,
                        const VectorXd& base_res, double sigma2_f, const std::vector<int>& logs, int periodic_log,
                        const std::function<bool(double)>& walk_survives, double pair_log_p, GyroCandidate* c) {
  const bool walk = c->cause == "rate_random_walk";
  if (c->cause == "periodic_drift" && FollowsReference(d, nm, bw, base_res, sigma2_f, {periodic_log}, c)) return true;
  if (c->cause == "scale_factor_asymmetry" && FollowsReference(d, nm, bw, base_res, sigma2_f, AzimuthLogs(d), c)) {
    return true;
  }
  if (FollowsTimeShape(d, nm, bw, base_res, sigma2_f, logs, walk ? walk_survives : std::function<bool(double)>(),
                       pair_log_p, c)) {
    return true;
  }
  const bool undriven = walk || c->cause == "periodic_drift" || c->cause == "bias_step";
  return undriven && FollowsLoggedColumn(d, nm, bw, base_res, sigma2_f, logs, c);
}

// Logs long enough to tell a random walk of the bias from the bounded wander.
std::vector<int> WalkLogs(const Design& d, const GyroDiscoverOptions& o) {
  std::vector<int> walk_logs;
  for (int r = 0; r < static_cast<int>(d.bins.size()); ++r) {
    if (d.bins[r].t_s.back() - d.bins[r].t_s.front() + d.bins[r].bin_s >= o.rrw_min_log_s) walk_logs.push_back(r);
  }
  return walk_logs;
}

// Two candidates that can join one model: both significant, different causes, neither the walk (a noise
// model, not columns), not a nested pair (they share a column).
bool Partners(const GyroCandidate& a, const GyroCandidate& b, const std::map<std::string, Fitted>& fits) {
  return a.applicable && a.significant && b.applicable && b.significant && a.cause != b.cause &&
         a.cause != "rate_random_walk" && b.cause != "rate_random_walk" && !NestedPair(a.cause, b.cause) &&
         fits.count(Key(a)) && fits.count(Key(b));
}

// The design of base + both candidates' terms.
MatrixXd PairDesign(const Design& d, const Fitted& fa, const Fitted& fb) {
  const int lb = static_cast<int>(d.base.cols());
  MatrixXd x(d.n, fa.x.cols() + fb.x.cols() - lb);
  x << fa.x, fb.x.rightCols(fb.x.cols() - lb);
  return x;
}

// Step 4: the significant candidates ordered by the smallest BIC of the exact likelihood (noise
// model refitted by maximum likelihood on each log's residual), so that a deterministic cause and a
// random walk, or a step and a walk, compete on the same footing. Sets each one's bic, and best_pair_bic to
// the lowest BIC of two of them together (Partners; infinity when no two can join).
std::vector<GyroCandidate*> BicOrder(const Design& d, const GyroDiscoverOptions& o, const std::vector<NoiseModel>& nm,
                                     const std::vector<int>& walk_logs, double walk_nll,
                                     const std::map<std::string, double>& position_cost,
                                     std::map<std::string, Fitted>* fits, std::vector<GyroCandidate>* candidates,
                                     double* best_pair_bic) {
  *best_pair_bic = std::numeric_limits<double>::infinity();
  std::vector<GyroCandidate*> order;
  for (auto& c : *candidates) {
    if (!c.applicable || !c.significant) continue;
    const double bic = CandidateBic(d, o, nm, c, walk_logs, walk_nll, fits, position_cost);
    c.bic = bic;
    order.push_back(&c);
  }
  // One step of look-ahead: a candidate ranks by the better of its own BIC and that of the best pair it
  // belongs to (Partners), counted only where the pair beats both alone by more than kBareMentionBic (a
  // second cause the data support), ties by its own. A greedy order by single BIC misleads when two causes share the
  // drift: with a temperature drift and a bias step, a field harmonic had the best BIC alone (the noise model refitted
  // on each residual absorbs the slow part either single cause leaves), was named first, and the pair was never
  // reached.
  std::map<const GyroCandidate*, double> score;
  for (GyroCandidate* c : order) score[c] = c->bic;
  for (size_t i = 0; i < order.size(); ++i) {
    for (size_t j = i + 1; j < order.size(); ++j) {
      const GyroCandidate &a = *order[i], &b = *order[j];
      if (!Partners(a, b, *fits)) continue;
      double cost = 0;
      for (const std::string& cause : {a.cause, b.cause}) {
        if (position_cost.count(cause)) cost += position_cost.at(cause);
      }
      const double bic = FittedBic(d, o, nm, PairDesign(d, fits->at(Key(a)), fits->at(Key(b))), a.dof + b.dof, cost);
      *best_pair_bic = std::min(*best_pair_bic, bic);
      if (bic + kBareMentionBic < std::min(a.bic, b.bic))
        score[&a] = std::min(score[&a], bic), score[&b] = std::min(score[&b], bic);
    }
  }
  std::sort(order.begin(), order.end(), [&](const GyroCandidate* a, const GyroCandidate* b) {
    return score[a] != score[b] ? score[a] < score[b] : a->bic < b->bic;
  });
  return order;
}

// The best ln p of candidate c's terms together with those of another significant candidate (not
// rate_random_walk, not c's nested partner, i.e. sharing no column), both against the base model as
// TestCandidates scores one (chi^2 with the summed dof, the located ones' scan corrections added); 0 when
// there is no partner.
double BestPairLogP(const Design& d, const std::vector<NoiseModel>& nm, const ScoreNorm& sn,
                    const std::vector<GyroCandidate>& candidates, const std::map<std::string, Fitted>& fits,
                    const std::map<std::string, double>& position_cost, const GyroCandidate& c) {
  double best = 0;
  for (const auto& p : candidates) {
    if (!Partners(c, p, fits)) continue;
    const LsFit g = SolveLs(WhitenRows(d, nm, PairDesign(d, fits.at(Key(c)), fits.at(Key(p)))), sn.y_w);
    const double stat = std::max(0.0, (sn.base_rss - g.rss) / (sn.s2 * sn.infl));
    double log_p = LogChi2Survival(stat, c.dof + p.dof);
    for (const std::string& cause : {c.cause, p.cause}) {
      if (position_cost.count(cause)) log_p += position_cost.at(cause);
    }
    best = std::min(best, log_p);
  }
  return std::min(0.0, best);
}

// thermal_lag is named only when its BIC is below that of temperature and temperature_gradient together,
// its lag is significant (the likelihood ratio against tau = 0, which is the temperature itself, beyond 3
// sigma, both with K20) and it predicts the held-out blocks better than temperature and
// temperature_gradient do (both are eq. (1)'s view of the same drift: a lag's drift on a ramp is K10
// plus a K01 term). True when refused; the verdict says why.
template <typename Evaluate, typename PairBic>
bool LagBeatenOnHeldOut(const Evaluation& ev, std::vector<GyroCandidate>& candidates, const Evaluate& evaluate,
                        const PairBic& pair_bic, GyroCandidate* c) {
  if (c->cause != "thermal_lag") return false;
  // K10 + K20 + K01 together describe a lag's drift (eq. (1) to first order in tau): the lag, one
  // coefficient and a located tau, must have the lower BIC of the exact likelihood.
  if (pair_bic() <= c->bic) {
    c->verdict = "temperature and temperature_gradient together fit as well (BIC)";
    return true;
  }
  if (!(ev.parameters.at("lag_vs_none_chi2") > kLagMinTauZ * kLagMinTauZ)) {
    c->verdict = "time constant not significant (the temperature itself)";
    return true;
  }
  for (GyroCandidate& rival : candidates) {
    if ((rival.cause != "temperature" && rival.cause != "temperature_gradient") || !rival.applicable) continue;
    const Evaluation er = evaluate(rival);
    if (er.cv.rms_after <= ev.cv.rms_after) {
      c->verdict = "held-out RMS not below " + rival.cause + "'s";
      return true;
    }
  }
  return false;
}

}  // namespace

GyroStep RunGyroStep(const Design& d, const GyroDiscoverOptions& o, const std::vector<bool>& usable,
                     const std::vector<double>& scale, const std::vector<int>& full_cols,
                     const std::set<std::string>& excluded, double alpha, double gain_alpha,
                     const std::string& first_file) {
  const int l = static_cast<int>(d.bins.size());
  GyroStep out;
  // Two passes: the step of `bias_step` and the sinusoid of `periodic_drift` are located with the
  // noise model of the full model, then added to the full model (so that they do not inflate the
  // fitted wander) and the noise model, the GLS and the scans are redone.
  MatrixXd x_full, bw;
  std::vector<NoiseModel> nm;
  std::vector<double> log_var;
  VectorXd yw, base_res;
  LsFit full, base;
  double sigma2 = 1, f = 1;
  StepScan step_scan;
  PeriodicScan periodic_scan;
  for (int pass = 0; pass < 2; ++pass) {
    // 1. OLS of the full model -> per-log noise model.
    // The located step and sinusoid join the full model in the second pass, so that they do not
    // inflate the fitted wander (a wander fitted with a sinusoid in it whitens the sinusoid away).
    std::vector<VectorXd> extra;
    if (pass == 1 && step_scan.best_step.size() == d.n) extra.push_back(step_scan.best_step);
    if (pass == 1 && periodic_scan.best_sin.size() == d.n) {
      extra.push_back(periodic_scan.best_sin), extra.push_back(periodic_scan.best_cos);
    }
    x_full = Assemble(d, full_cols, extra);
    const LsFit ols = SolveLs(x_full, d.y);
    if (!ols.ok) throw InputError(first_file, "degenerate regressors");
    const VectorXd e_ols = d.y - x_full * ols.beta;
    FitLogNoise(d, o, x_full, e_ols, &nm, &log_var);
    // 2. GLS of the full model; effective sample size from the whitened residuals.
    yw = WhitenRows(d, nm, d.y);
    const MatrixXd xw_full = WhitenRows(d, nm, x_full);
    full = SolveLs(xw_full, yw);
    const VectorXd ew = yw - xw_full * full.beta;
    sigma2 = full.rss / std::max(1, d.n - static_cast<int>(x_full.cols()));
    f = VarianceInflation(d, ew, o.max_noise_lag);
    bw = WhitenRows(d, nm, d.base);
    base = SolveLs(bw, yw);
    base_res = yw - bw * base.beta;
    ScanStep(d, nm, bw, base_res, sigma2 * f, &step_scan);
    ScanPeriodic(d, nm, bw, base_res, o, pass, sigma2 * f, &periodic_scan);
  }
  out.inflation = f;
  out.nm = nm;
  out.periodic_log = periodic_scan.best_periodic_log;

  // 3. Candidates (those named at earlier steps, and their nested partners, are left out).
  std::vector<CandidateSpec> specs;
  for (const CandidateSpec& sp : std::vector<CandidateSpec>{
           {"temperature", "", {kT1, kT2}, {kT1, kT2}},
           {"temperature_gradient", "", {kG1}, {kG1}},
           {"thermal_lag", "", {kLag}, {kLag}},
           {"magnetic_field", "azimuth_harmonic", {kMagSin, kMagCos}, {kMagSin, kMagCos}},
           {"magnetic_field", "logged_field", {kBn, kBe, kBh}, {}},
           {"misalignment", "", {kMis}, {kMis}},
           {"scale_factor", "", {kScale}, {kScale}},
           {"scale_factor_asymmetry", "", {kScale, kAbsRef}, {kScale, kAbsRef}},
           {"time_delay", "", {kDelay}, {kDelay}},
       }) {
    if (!excluded.count(sp.cause)) specs.push_back(sp);
  }
  const std::vector<int> walk_logs = excluded.count("rate_random_walk") ? std::vector<int>() : WalkLogs(d, o);
  if (excluded.count("bias_step")) step_scan.best_step.resize(0);
  if (excluded.count("periodic_drift")) periodic_scan.best_sin.resize(0);
  const bool step_ok = step_scan.best_step.size() == d.n, periodic_ok = periodic_scan.best_sin.size() == d.n;
  int tested = step_ok + periodic_ok + !walk_logs.empty();
  for (const auto& sp : specs) tested += !SpecColumns(sp, usable).empty();
  const double alpha_each = alpha / std::max(tested, 1);
  out.alpha_each = alpha_each;
  std::map<std::string, Fitted> fits;
  std::map<std::string, double> position_cost;  // ln(positions scanned) of the located candidates
  // Every deterministic candidate and the located step and sinusoid against the base model, with
  // GLS under the per-log noise models `noise` and the inflation of the full model's whitened residuals.
  std::vector<GyroCandidate>& candidates = out.candidates;
  candidates =
      TestCandidates(d, o, nm, x_full, specs, usable, alpha_each, step_scan, periodic_scan, &fits, &position_cost);

  // rate_random_walk: likelihood ratio of the noise model with a random walk of the bias against
  // the base noise model (white + Gauss-Markov wander with tau <= wander_tau_max_s), both by
  // maximum likelihood on each long log's base-model residuals. q = 0 lies on the boundary, so the
  // LR follows 0.5 chi2_0 + 0.5 chi2_1 (Self & Liang 1987).
  const WalkTest walk = TestRandomWalk(d, o, nm, walk_logs, alpha_each, d.n / f);
  if (!excluded.count("rate_random_walk")) candidates.push_back(walk.candidate);
  // 4. Order of the significant candidates (BicOrder).
  double best_pair_bic = 0;
  std::vector<GyroCandidate*> order =
      BicOrder(d, o, nm, walk_logs, walk.nll, position_cost, &fits, &candidates, &best_pair_bic);
  // A random walk of the bias is one parameter for every slow structure at once: with two deterministic
  // causes in the logs it beat each alone in BIC (a bias step with a temperature drift was named
  // rate_random_walk 2 of 30 times, and the walk ends the chain). It goes last among the significant
  // candidates when two of them together (Partners) have a lower BIC of the exact likelihood than the walk's.
  if (!order.empty() && order.front()->cause == "rate_random_walk" && best_pair_bic < order.front()->bic) {
    std::rotate(order.begin(), order.begin() + 1, order.end());
  }
  // Nested pairs: misalignment is a harmonic of fixed phase inside magnetic_field, scale_factor is
  // scale_factor_asymmetry with equal scale factors for both signs. The larger model is taken when
  // its extra terms are themselves significant (chi^2 of the difference, a follow-up test at alpha: a choice
  // between two models of one effect, not a further cause, so at every step the same alpha).
  auto upgrade = [&](GyroCandidate* c) { return Upgrade(c, &candidates, o.alpha); };

  // 5. Gates, in BIC order: the first candidate whose parameters lie within the physical bounds and
  // whose held-out improvement is significant is named.
  out.z_min = boost::math::quantile(
      boost::math::complement(boost::math::normal(), gain_alpha / l));  // Bonferroni over the logs
  auto evaluate = [&](const GyroCandidate& cand) {
    const std::string& cause = cand.cause;
    Evaluation ev;
    if (cause == "rate_random_walk") {
      EvaluateWalk(d, o, walk_logs, log_var, walk.nm_walk[walk.log].q_rw, walk.log, walk.lnq_sigma, &ev);
    } else {
      EvaluateFitted(d, o, nm, fits[Key(cand)], cause, scale, step_scan, periodic_scan, &ev);
    }
    ev.out_of_bounds = OutOfBounds(cause, ev.parameters);
    return ev;
  };

  auto walk_survives = [&](double tau_s) { return WalkBeatsShape(d, o, nm, walk_logs, tau_s); };
  const ScoreNorm norm = MakeScoreNorm(d, o, nm, x_full);
  auto pair_bic = [&] {
    std::vector<int> cols;
    for (int col : {kT1, kT2, kG1}) {
      if (usable[col]) cols.push_back(col);
    }
    return FittedBic(d, o, nm, Assemble(d, cols, {}), static_cast<int>(cols.size()), 0.0);
  };
  const GyroCandidate* chosen = nullptr;
  std::vector<std::string> tried;
  for (GyroCandidate* c0 : order) {
    for (GyroCandidate* c : {upgrade(c0), c0}) {
      if (chosen || std::find(tried.begin(), tried.end(), Key(*c)) != tried.end()) continue;
      tried.push_back(Key(*c));
      const std::vector<int> c_logs = c->cause == "rate_random_walk" ? walk_logs : CandidateLogs(d, fits[Key(*c)]);
      const double pair_log_p = BestPairLogP(d, nm, norm, candidates, fits, position_cost, *c);
      if (ExplainedOtherwise(d, nm, bw, base_res, sigma2 * f, c_logs, periodic_scan.best_periodic_log, walk_survives,
                             pair_log_p, c)) {
        continue;
      }
      Evaluation ev = evaluate(*c);
      if (JudgeCandidate(ev, out.z_min, o, c) && !LagBeatenOnHeldOut(ev, candidates, evaluate, pair_bic, c)) {
        chosen = c, out.cause.ev = ev;
      }
    }
    if (chosen) break;
  }
  if (!chosen) return out;
  out.named = true;
  NamedCause& nc = out.cause;
  nc.candidate = *chosen;
  nc.nm = nm;
  if (chosen->cause == "rate_random_walk") {
    nc.nm_walk = walk.nm_walk;
  } else {
    nc.cols = fits.at(Key(*chosen)).cols;
    if (position_cost.count(chosen->cause)) nc.position_cost = position_cost.at(chosen->cause);
    if (chosen->cause == "bias_step") nc.extra = {step_scan.best_step}, nc.step_scan = step_scan;
    if (chosen->cause == "periodic_drift") {
      nc.extra = {periodic_scan.best_sin, periodic_scan.best_cos}, nc.periodic_scan = periodic_scan;
    }
  }
  return out;
}

}  // namespace ssiu::discover_internal
