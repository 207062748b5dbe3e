// The noise model of `ssiu discover gyro` (white + Gauss-Markov wander, optionally a random walk) and its
// Kalman whitening; its fits (moments, maximum likelihood, REML); least squares and the GLS helpers on the
// design.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <vector>

#include "discover/discover_gyro_internal.h"

namespace ssiu::discover_internal {

// The Kalman filter of the wander x and the level b (H = [1 1]): its gain and 1/sqrt(S_k) per bin.
// P = [a b; c d], F = diag(phi, 1), Q = diag(var_g (1 - phi^2), q_rw): P <- F P F' + Q, S = sum(P) + var_w,
// K = P [1 1]' / S, P <- P - K [1 1] P. Written out in scalars, each sum in the order Eigen's 2x2 products
// take (the same bits: checked on 4e6 random steps, gcc -O3 and clang -O1 with the sanitizers), as
// Eigen's fixed-size expressions are not inlined in the sanitizer build, where they took half of a
// discovery's time.
void NoiseModel::Prepare(int m) {
  gain.assign(m, Eigen::Vector2d::Zero());
  inv_sqrt_s.assign(m, 0);
  const double g0 = var_w + var_g;
  double a = var_g, b = 0, c = 0;
  double d = (q_rw > 0 || diffuse_level) && !known_level ? kDiffuse * g0 : 0.0;
  const double q_g = var_g * (1 - phi * phi);
  for (int k = 0; k < m; ++k) {
    if (k > 0) a = phi * a * phi + q_g, b = phi * b, c = c * phi, d = d + q_rw;
    const double s = ((a + b) + (c + d)) + var_w;  // H P H' + R
    const double k0 = (a + b) / s, k1 = (c + d) / s;
    gain[k] = Eigen::Vector2d(k0, k1);
    inv_sqrt_s[k] = 1 / std::sqrt(s);
    const double h0 = a + c, h1 = b + d;  // H P
    a = a - k0 * h0, b = b - k0 * h1, c = c - k1 * h0, d = d - k1 * h1;
  }
}

namespace {

// The one Kalman recursion on N series: per bin, the innovation e = v - (x + b) over sqrt(S_k), then
// the state update; the operations of each series in Whiten's order, so that every result is the same.
template <int N>
void WhitenN(const NoiseModel& nm, const double* const* in, double* const* out, int m, int from = 0) {
  double x[N] = {}, b[N] = {};
  for (int k = from; k < m; ++k) {
    const double g0 = nm.gain[k](0), g1 = nm.gain[k](1), is = nm.inv_sqrt_s[k];
    for (int c = 0; c < N; ++c) {
      if (k > 0) x[c] *= nm.phi;
      const double e = in[c][k] - (x[c] + b[c]);
      out[c][k] = e * is;
      x[c] += g0 * e;
      b[c] += g1 * e;
    }
  }
}

}  // namespace

void NoiseModel::WhitenSeries(const double* const* in, double* const* out, int n, int m, int from) const {
  switch (n) {
    case 1:
      return WhitenN<1>(*this, in, out, m, from);
    case 2:
      return WhitenN<2>(*this, in, out, m, from);
    case 3:
      return WhitenN<3>(*this, in, out, m, from);
    case 4:
      return WhitenN<4>(*this, in, out, m, from);
    default:
      for (int c = 0; c < n; c += 4) WhitenSeries(in + c, out + c, std::min(4, n - c), m, from);
  }
}

VectorXd NoiseModel::Whiten(const VectorXd& v) const {
  VectorXd out(v.size());
  const double* in = v.data();
  double* o = out.data();
  WhitenN<1>(*this, &in, &o, static_cast<int>(v.size()));
  return out;
}

// The same recursion on each column of x, four at a time.
MatrixXd NoiseModel::WhitenCols(const MatrixXd& x) const {
  MatrixXd out(x.rows(), x.cols());
  for (int c = 0; c < x.cols(); c += 4) {
    const int n = std::min<int>(4, static_cast<int>(x.cols()) - c);
    const double* in[4];
    double* o[4];
    for (int j = 0; j < n; ++j) in[j] = x.col(c + j).data(), o[j] = out.col(c + j).data();
    WhitenSeries(in, o, n, static_cast<int>(x.rows()));
  }
  return out;
}

double NoiseModel::NegLogLik(const VectorXd& v) const {
  const VectorXd w = Whiten(v);
  double nll = 0;
  for (int k = 1; k < v.size(); ++k) nll += 0.5 * w(k) * w(k) + std::log(1 / inv_sqrt_s[k]);
  return nll;
}

namespace {

// Nelder & Mead (1965) simplex minimiser, for the few noise parameters (in log space).
VectorXd NelderMead(const std::function<double(const VectorXd&)>& fn, VectorXd x0, double step, int iters) {
  const int n = static_cast<int>(x0.size());
  std::vector<VectorXd> pts(n + 1, x0);
  std::vector<double> val(n + 1);
  for (int i = 0; i < n; ++i) pts[i + 1](i) += step;
  for (int i = 0; i <= n; ++i) val[i] = fn(pts[i]);
  for (int it = 0; it < iters; ++it) {
    std::vector<int> idx(n + 1);
    std::iota(idx.begin(), idx.end(), 0);
    std::sort(idx.begin(), idx.end(), [&](int a, int b) { return val[a] < val[b]; });
    const int best = idx[0], worst = idx[n], second = idx[n - 1];
    if (std::abs(val[worst] - val[best]) < 1e-9 * (1 + std::abs(val[best]))) break;
    VectorXd c = VectorXd::Zero(n);
    for (int i = 0; i < n; ++i) c += pts[idx[i]] / n;
    const VectorXd xr = c + (c - pts[worst]);
    const double fr = fn(xr);
    if (fr < val[best]) {
      const VectorXd xe = c + 2 * (c - pts[worst]);
      const double fe = fn(xe);
      if (fe < fr)
        pts[worst] = xe, val[worst] = fe;
      else
        pts[worst] = xr, val[worst] = fr;
    } else if (fr < val[second]) {
      pts[worst] = xr, val[worst] = fr;
    } else {
      const VectorXd xc = c + 0.5 * (pts[worst] - c);
      const double fc = fn(xc);
      if (fc < val[worst]) {
        pts[worst] = xc, val[worst] = fc;
      } else {
        for (int i = 0; i <= n; ++i) {
          if (i == best) continue;
          pts[i] = pts[best] + 0.5 * (pts[i] - pts[best]);
          val[i] = fn(pts[i]);
        }
      }
    }
  }
  int best = 0;
  for (int i = 1; i <= n; ++i) best = val[i] < val[best] ? i : best;
  return pts[best];
}

}  // namespace

// Maximum-likelihood noise model of residual v with the wander's correlation time bounded by
// tau_max (phi = exp(-bin / tau), tau = tau_max * logistic(u)); with_walk adds the random walk.
NoiseMle FitNoiseMle(const VectorXd& v, double bin_s, double tau_max_s, const NoiseModel& start, bool with_walk,
                     int iters) {
  const int m = static_cast<int>(v.size());
  const double g0 = std::max(v.squaredNorm() / m, 1e-30);
  auto make = [&](const VectorXd& p) {
    NoiseModel nm;
    nm.var_w = std::exp(p(0)) * g0;
    nm.var_g = std::exp(p(1)) * g0;
    const double tau = tau_max_s / (1 + std::exp(-p(2)));
    nm.phi = std::exp(-bin_s / std::max(tau, 1e-9));
    nm.q_rw = with_walk ? std::exp(p(3)) * g0 : 0.0;
    nm.diffuse_level = true;
    nm.Prepare(m);
    return nm;
  };
  auto fn = [&](const VectorXd& p) {
    if (!p.allFinite() || p.cwiseAbs().maxCoeff() > 60) return 1e300;
    return make(p).NegLogLik(v);
  };
  VectorXd p0(with_walk ? 4 : 3);
  p0(0) = std::log(std::max(start.var_w, 1e-6 * g0) / g0);
  p0(1) = std::log(std::max(start.var_g, 1e-6 * g0) / g0);
  const double tau0 = start.phi > 0 && start.phi < 1 ? -bin_s / std::log(start.phi) : 0.5 * tau_max_s;
  const double r = std::clamp(tau0 / tau_max_s, 1e-6, 1 - 1e-6);
  p0(2) = std::log(r / (1 - r));
  if (with_walk) {
    p0(3) = std::log(std::max(start.q_rw, 1e-8) / g0);
  }
  VectorXd p = NelderMead(fn, p0, iters >= 600 ? 1.0 : 0.3, iters);
  p = NelderMead(fn, p, 0.3, iters / 2);  // restart: the simplex may have collapsed early
  NoiseMle res;
  res.model = make(p);
  res.nll = fn(p);
  if (with_walk) {  // curvature in ln q (other parameters held) -> a rough sigma of ln q
    const double h = 0.05;
    VectorXd a = p, b = p;
    a(3) += h;
    b(3) -= h;
    const double d2 = (fn(a) - 2 * res.nll + fn(b)) / (h * h);
    res.ln_q_sigma = d2 > 0 ? 1 / std::sqrt(d2) : 1.0;
  }
  return res;
}

// phi_max bounds the wander's correlation time (the base model's wander is slow but bounded).
NoiseModel FitNoise(const VectorXd& e, int max_lag, double phi_max) {
  const int m = static_cast<int>(e.size());
  const int lags = std::min(max_lag, m / 3);
  std::vector<double> gamma(lags + 1, 0);
  for (int k = 0; k <= lags; ++k) {
    for (int i = k; i < m; ++i) gamma[k] += e(i) * e(i - k);
    gamma[k] /= (m - k);
  }
  NoiseModel nm;
  nm.var_w = std::max(gamma[0], 1e-30);
  // Log-linear fit of gamma_k, k >= 1 (as fog_thermal.cc): slope ln phi, intercept ln g.
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int cnt = 0;
  for (int k = 1; k <= lags && gamma[k] > 0; ++k) {
    sx += k;
    sy += std::log(gamma[k]);
    sxx += k * k;
    sxy += k * std::log(gamma[k]);
    ++cnt;
  }
  if (cnt >= 2 && gamma[0] > 0) {
    double slope = (cnt * sxy - sx * sy) / (cnt * sxx - sx * sx);
    slope = std::min(slope, std::log(phi_max));  // intercept refitted with the bounded slope
    nm.phi = std::clamp(std::exp(slope), 0.0, phi_max);
    nm.var_g = std::clamp(std::exp((sy - slope * sx) / cnt), 0.0, gamma[0]);
    nm.var_w = std::max(gamma[0] - nm.var_g, 1e-6 * gamma[0]);
  } else if (cnt == 1 && gamma[0] > 0) {
    nm.phi = std::clamp(gamma[1] / gamma[0], 0.0, phi_max);
    nm.var_g = gamma[1] / std::max(nm.phi, 1e-9);
    nm.var_g = std::min(nm.var_g, gamma[0]);
    nm.var_w = std::max(gamma[0] - nm.var_g, 1e-6 * gamma[0]);
  }
  nm.Prepare(m);
  return nm;
}

LsFit SolveLs(const MatrixXd& x, const VectorXd& y) {
  LsFit f;
  const MatrixXd a = x.transpose() * x;
  const double ridge = 1e-12 * std::max(a.trace(), 1e-300);
  Eigen::LDLT<MatrixXd> ldlt(a + ridge * MatrixXd::Identity(a.rows(), a.cols()));
  if (ldlt.info() != Eigen::Success) return f;
  f.beta = ldlt.solve(x.transpose() * y);
  f.cov_unscaled = ldlt.solve(MatrixXd::Identity(a.rows(), a.cols()));
  f.rss = (y - x * f.beta).squaredNorm();
  f.ok = f.beta.allFinite();
  return f;
}

// The residual of the base model by ordinary least squares: each log's drift minus its mean while the base
// holds only the biases (as the tests of one step always had it), else minus the named causes' fit too.
VectorXd LevelResidual(const Design& d) {
  const int l = static_cast<int>(d.bins.size());
  if (d.base.cols() > l) return d.y - d.base * SolveLs(d.base, d.y).beta;
  VectorXd v = d.y;
  for (int r = 0; r < l; ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    v.segment(d.offset[r], m).array() -= v.segment(d.offset[r], m).mean();
  }
  return v;
}

// Columns of `names` (kNumCols indices) plus optional extra columns, with the base in front.
MatrixXd Assemble(const Design& d, const std::vector<int>& which, const std::vector<VectorXd>& extra) {
  const int l = static_cast<int>(d.base.cols());
  MatrixXd x(d.n, l + which.size() + extra.size());
  x.leftCols(l) = d.base;
  for (size_t j = 0; j < which.size(); ++j) x.col(l + j) = d.cols.col(which[j]);
  for (size_t j = 0; j < extra.size(); ++j) x.col(l + which.size() + j) = extra[j];
  return x;
}

MatrixXd WhitenRows(const Design& d, const std::vector<NoiseModel>& nm, const MatrixXd& x) {
  MatrixXd out(x.rows(), x.cols());
  for (size_t r = 0; r < d.bins.size(); ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    for (int c = 0; c < x.cols(); c += 4) {
      const int n = std::min<int>(4, static_cast<int>(x.cols()) - c);
      const double* in[4];
      double* o[4];
      for (int j = 0; j < n; ++j) in[j] = x.col(c + j).data() + d.offset[r], o[j] = out.col(c + j).data() + d.offset[r];
      nm[r].WhitenSeries(in, o, n, m);
    }
  }
  return out;
}

// Variance inflation n / n_eff = 1 + 2 sum_k (1 - k/(L+1)) r_k of whitened residuals (Bartlett-
// weighted integrated autocorrelation, pooled over logs), as in fog_thermal.h.
double VarianceInflation(const Design& d, const VectorXd& ew, int lag_max) {
  double f = 1;
  for (int k = 1; k <= lag_max; ++k) {
    double num = 0, den = 0;
    for (size_t r = 0; r < d.bins.size(); ++r) {
      const int m = static_cast<int>(d.bins[r].t_s.size());
      for (int i = 0; i < m; ++i) {
        const double a = ew(d.offset[r] + i);
        den += a * a;
        if (i >= k) num += a * ew(d.offset[r] + i - k);
      }
    }
    f += 2 * (1 - k / (lag_max + 1.0)) * (den > 0 ? num / den : 0.0);
  }
  return std::clamp(f, 1.0, 20.0);
}

// The noise model with a random walk of the bias by maximum likelihood, from the walkless fit h0: the
// likelihood is flat in ln q near q = 0, so it starts from several walk strengths.
NoiseMle FitWalkMle(const VectorXd& v, double bin_s, double tau_max_s, const NoiseModel& h0) {
  NoiseMle h1;
  h1.nll = std::numeric_limits<double>::infinity();
  for (double rel : {1e-5, 1e-3, 1e-2, 1e-1}) {
    NoiseModel start = h0;
    start.q_rw = rel * (h0.var_w + h0.var_g);
    NoiseMle h = FitNoiseMle(v, bin_s, tau_max_s, start, true);
    if (h.nll < h1.nll) h1 = h;
  }
  return h1;
}

// 6. The noise model of each log of the residual e_fit (per-log mean removed).
void RefitResidualNoise(const Design& d, const GyroDiscoverOptions& o, const VectorXd& e_fit,
                        std::vector<NoiseModel>* noise_fit) {
  const int l = static_cast<int>(d.bins.size());
  for (int r = 0; r < l; ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    VectorXd v = e_fit.segment(d.offset[r], m);
    v.array() -= v.mean();
    (*noise_fit)[r] = FitNoise(v, o.max_noise_lag, std::exp(-d.bins[r].bin_s / o.wander_tau_max_s));
  }
}

// Restricted maximum likelihood (REML; Patterson & Thompson 1971, for time series Tunnicliffe Wilson 1989)
// of the white + Gauss-Markov noise of one log y (m bins) under the regressors x (m x k, full column
// rank; the log's bias among them): -ln L_R = 0.5 [ln|V| + ln|X' V^-1 X| + y' P y], P the GLS residual
// projector, all through the noise model's Kalman whitening. Unlike the moment fit of the OLS residual,
// it counts what the regressors can absorb of a slow wander: a realisation whose slow power the full
// model's many slow columns partly take up is not read as a weaker wander. Wander tau <= tau_max_s, as
// FitNoiseMle; starts from `start`.
NoiseModel FitNoiseReml(const VectorXd& y, const MatrixXd& x, double bin_s, double tau_max_s, const NoiseModel& start) {
  const int m = static_cast<int>(y.size()), k = static_cast<int>(x.cols());
  MatrixXd xy(m, k + 1);
  xy << x, y;
  const double g0 = std::max(start.var_w + start.var_g, 1e-30);
  auto make = [&](const VectorXd& p) {
    NoiseModel nm;
    nm.var_w = std::exp(p(0)) * g0;
    nm.var_g = std::exp(p(1)) * g0;
    nm.phi = std::exp(-bin_s / std::max(tau_max_s / (1 + std::exp(-p(2))), 1e-9));
    nm.Prepare(m);
    return nm;
  };
  auto fn = [&](const VectorXd& p) {
    if (!p.allFinite() || p.cwiseAbs().maxCoeff() > 40) return 1e300;
    const NoiseModel nm = make(p);
    const MatrixXd xyw = nm.WhitenCols(xy);
    const MatrixXd xw = xyw.leftCols(k);
    const VectorXd yw = xyw.col(k);
    const Eigen::LDLT<MatrixXd> ldlt(xw.transpose() * xw);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0)) return 1e300;
    const VectorXd xty = xw.transpose() * yw;
    const double rss = yw.squaredNorm() - xty.dot(ldlt.solve(xty));
    double nll = 0.5 * ldlt.vectorD().array().log().sum() + 0.5 * std::max(rss, 0.0);
    for (int i = 0; i < m; ++i) nll -= std::log(nm.inv_sqrt_s[i]);
    return nll;
  };
  VectorXd p0(3);
  p0(0) = std::log(std::max(start.var_w, 1e-4 * g0) / g0);
  p0(1) = std::log(std::max(start.var_g, 1e-4 * g0) / g0);
  const double tau0 = start.phi > 0 && start.phi < 1 ? -bin_s / std::log(start.phi) : 0.5 * tau_max_s;
  const double r = std::clamp(tau0 / tau_max_s, 1e-4, 1 - 1e-4);
  p0(2) = std::log(r / (1 - r));
  VectorXd p = NelderMead(fn, p0, 1.0, 300);
  p = NelderMead(fn, p, 0.3, 150);  // restart: the simplex may have collapsed early
  return fn(p) <= fn(p0) ? make(p) : start;
}

// 1. The per-log noise model of the full model x_full (OLS residual e_ols): the moment fit of the
// residual's autocovariance as the start, then REML with the log's rows of x_full (its columns that
// are not zero there, reduced to an orthonormal basis of their span) as the regressors; and each log's
// variance.
void FitLogNoise(const Design& d, const GyroDiscoverOptions& o, const MatrixXd& x_full, const VectorXd& e_ols,
                 std::vector<NoiseModel>* nm, std::vector<double>* log_var) {
  const int l = static_cast<int>(d.bins.size());
  nm->clear();
  log_var->clear();
  for (int r = 0; r < l; ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    const double phi_max = std::exp(-d.bins[r].bin_s / o.wander_tau_max_s);
    const NoiseModel start = FitNoise(e_ols.segment(d.offset[r], m), o.max_noise_lag, phi_max);
    const Eigen::JacobiSVD<MatrixXd> svd(x_full.middleRows(d.offset[r], m), Eigen::ComputeThinU);
    const VectorXd& sv = svd.singularValues();
    int rank = 0;
    while (rank < sv.size() && sv(rank) > 1e-8 * sv(0)) ++rank;
    nm->push_back(FitNoiseReml(d.y.segment(d.offset[r], m), svd.matrixU().leftCols(rank), d.bins[r].bin_s,
                               o.wander_tau_max_s, start));
    log_var->push_back(nm->back().var_w + nm->back().var_g);
  }
}

// Evidence: the noise of the longest log.
void ReportLongestLogNoise(const Design& d, const std::vector<NoiseModel>& nm, GyroDiscovery* res) {
  const int l = static_cast<int>(d.bins.size());
  int best = 0;
  for (int r = 1; r < l; ++r) {
    if (d.bins[r].t_s.size() * d.bins[r].bin_s > d.bins[best].t_s.size() * d.bins[best].bin_s) best = r;
  }
  res->noise_white_dph = std::sqrt(nm[best].var_w);
  res->noise_wander_dph = std::sqrt(nm[best].var_g);
  res->noise_wander_tau_s = nm[best].phi > 0 ? -d.bins[best].bin_s / std::log(nm[best].phi) : 0.0;
}

}  // namespace ssiu::discover_internal
