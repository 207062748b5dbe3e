#include "analysis/discover_gyro.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>

#include "core/csv.h"
#include "core/error.h"
#include "core/rng.h"
#include "core/types.h"

namespace ssiu {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

constexpr double kArcsecPerRad = 206264.80624709636;

// Candidate regressor columns (bin means), in this fixed order.
enum Col { kT1, kT2, kG1, kMagSin, kMagCos, kMis, kScale, kDelay, kNumCols };

struct LogBins {
  double bin_s = 0;
  std::vector<double> t_s, y_dph;
  std::vector<std::array<double, kNumCols>> x;
};

LogBins MakeLogBins(const GyroBenchLog& log, const GyroDiscoverOptions& o) {
  const size_t n = log.t_s.size();
  const double duration = log.t_s.back() - log.t_s.front();
  const double dt = duration / static_cast<double>(n - 1);
  LogBins b;
  b.bin_s = std::max(dt, duration / o.max_bins_per_log);
  // Per-sample regressors that need neighbours: d(ref)/dt (central differences) and the
  // misalignment regressor d(ref)/d(psi) from the harmonic of ref in azimuth.
  std::vector<double> dref(n, 0.0), dref_dpsi(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    const size_t a = i == 0 ? 0 : i - 1, c = i + 1 < n ? i + 1 : n - 1;
    dref[i] = (log.ref_dph[c] - log.ref_dph[a]) / (log.t_s[c] - log.t_s[a]);
  }
  const bool has_az = !log.azimuth_deg.empty();
  if (has_az) {
    Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
    Eigen::Vector3d r = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < n; ++i) {
      const double p = log.azimuth_deg[i] * kDegToRad;
      const Eigen::Vector3d v(1, std::cos(p), std::sin(p));
      a += v * v.transpose();
      r += v * log.ref_dph[i];
    }
    const Eigen::Vector3d h = a.ldlt().solve(r);
    if (h.allFinite()) {
      for (size_t i = 0; i < n; ++i) {
        const double p = log.azimuth_deg[i] * kDegToRad;
        dref_dpsi[i] = (-h(1) * std::sin(p) + h(2) * std::cos(p)) / kArcsecPerRad;  // per arcsec
      }
    }
  }
  // Bin edges.
  const double t0 = log.t_s.front();
  const int nb = std::max(1, static_cast<int>(std::floor(duration / b.bin_s + 1e-9)));
  std::vector<double> sum_y(nb, 0), sum_t(nb, 0), cnt(nb, 0);
  std::vector<std::array<double, kNumCols>> sum_x(nb);
  for (auto& s : sum_x) s.fill(0);
  for (size_t i = 0; i < n; ++i) {
    const int k = std::min(nb - 1, static_cast<int>((log.t_s[i] - t0) / b.bin_s));
    sum_y[k] += log.w_dph[i] - log.ref_dph[i];
    sum_t[k] += log.t_s[i];
    cnt[k] += 1;
    auto& x = sum_x[k];
    if (has_az) {
      const double p = log.azimuth_deg[i] * kDegToRad;
      x[kMagSin] += std::sin(p);
      x[kMagCos] += std::cos(p);
      x[kMis] += dref_dpsi[i];
    }
    x[kScale] += log.ref_dph[i] * 1e-6;
    x[kDelay] += -dref[i];
  }
  for (int k = 0; k < nb; ++k) {
    if (cnt[k] == 0) continue;
    b.t_s.push_back(sum_t[k] / cnt[k]);
    b.y_dph.push_back(sum_y[k] / cnt[k]);
    auto x = sum_x[k];
    for (double& v : x) v /= cnt[k];
    b.x.push_back(x);
  }
  // Temperature terms at the bin centres (local polynomial of fog_thermal.h).
  const TemperatureEstimate te = EstimateTemperatureRate(log.t_s, log.temp_c, b.t_s, o.rate);
  ThermalDriftModel m;
  for (size_t k = 0; k < b.t_s.size(); ++k) {
    const double z1 = m.Z1(te.temp_c[k]), z2 = m.Z2(te.rate_c_per_min[k]);
    b.x[k][kT1] = z1;
    b.x[k][kT2] = z1 * z1;
    b.x[k][kG1] = z2;
  }
  return b;
}

// White + first-order Gauss-Markov noise of one log (autocovariance gamma_0 = w + g,
// gamma_k = g phi^k), optionally plus a random walk of the bias (variance q per bin), and the
// exact whitening by the innovations of its Kalman filter (states: wander x, walk level b; with a
// walk, b starts diffuse, so the log's constant bias is absorbed).
struct NoiseModel {
  double var_w = 1, var_g = 0, phi = 0, q_rw = 0;
  bool diffuse_level = false;  // b starts diffuse even without a walk (the likelihood of the null)
  std::vector<Eigen::Vector2d> gain;
  std::vector<double> inv_sqrt_s;  // per bin

  static constexpr double kDiffuse = 1e6;  // prior variance of b relative to the noise, with a walk

  void Prepare(int m) {
    gain.assign(m, Eigen::Vector2d::Zero());
    inv_sqrt_s.assign(m, 0);
    const double g0 = var_w + var_g;
    Eigen::Matrix2d p = Eigen::Matrix2d::Zero();
    p(0, 0) = var_g;
    p(1, 1) = q_rw > 0 || diffuse_level ? kDiffuse * g0 : 0.0;
    const Eigen::Matrix2d f = Eigen::Vector2d(phi, 1).asDiagonal();
    const Eigen::Matrix2d q = Eigen::Vector2d(var_g * (1 - phi * phi), q_rw).asDiagonal();
    for (int k = 0; k < m; ++k) {
      if (k > 0) p = f * p * f.transpose() + q;
      const double s = p.sum() + var_w;  // H = [1 1]
      const Eigen::Vector2d kg = p.rowwise().sum() / s;
      gain[k] = kg;
      inv_sqrt_s[k] = 1 / std::sqrt(s);
      p = p - kg * Eigen::RowVector2d(p.colwise().sum());
    }
  }
  // Whitened copy of v (length m): innovation / sqrt(S_k).
  VectorXd Whiten(const VectorXd& v) const {
    VectorXd out(v.size());
    Eigen::Vector2d xh = Eigen::Vector2d::Zero();
    for (int k = 0; k < v.size(); ++k) {
      if (k > 0) xh(0) *= phi;
      const double e = v(k) - xh.sum();
      out(k) = e * inv_sqrt_s[k];
      xh += gain[k] * e;
    }
    return out;
  }
  // Gaussian negative log-likelihood of v, leaving out the first (diffuse) innovation.
  double NegLogLik(const VectorXd& v) const {
    const VectorXd w = Whiten(v);
    double nll = 0;
    for (int k = 1; k < v.size(); ++k) nll += 0.5 * w(k) * w(k) + std::log(1 / inv_sqrt_s[k]);
    return nll;
  }
};

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
      if (fe < fr) pts[worst] = xe, val[worst] = fe;
      else pts[worst] = xr, val[worst] = fr;
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

// Maximum-likelihood noise model of residual v with the wander's correlation time bounded by
// tau_max (phi = exp(-bin / tau), tau = tau_max * logistic(u)); with_walk adds the random walk.
struct NoiseMle {
  NoiseModel model;
  double nll = 0, ln_q_sigma = 0;
};
NoiseMle FitNoiseMle(const VectorXd& v, double bin_s, double tau_max_s, const NoiseModel& start, bool with_walk) {
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
  VectorXd p = NelderMead(fn, p0, 1.0, 600);
  p = NelderMead(fn, p, 0.3, 300);  // restart: the simplex may have collapsed early
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

struct LsFit {
  VectorXd beta;
  MatrixXd cov_unscaled;  // (X^T X)^-1
  double rss = 0;
  bool ok = false;
};

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

double ChiSquaredSurvival(double w, int dof) {
  if (w <= 0) return 1.0;
  if (dof == 1) return std::erfc(std::sqrt(w / 2));
  if (dof == 2) return std::exp(-w / 2);
  return std::numeric_limits<double>::quiet_NaN();
}

struct Design {
  std::vector<LogBins> bins;
  std::vector<int> offset;  // first row of each log
  int n = 0;
  MatrixXd cols;             // n x kNumCols raw regressors
  VectorXd y;
  MatrixXd base;             // n x L per-log bias indicators
};

// Columns of `names` (kNumCols indices) plus optional extra columns, with the base in front.
MatrixXd Assemble(const Design& d, const std::vector<int>& which, const std::vector<VectorXd>& extra) {
  const int l = static_cast<int>(d.bins.size());
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
    for (int c = 0; c < x.cols(); ++c) {
      out.col(c).segment(d.offset[r], m) = nm[r].Whiten(x.col(c).segment(d.offset[r], m));
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

struct CandidateSpec {
  std::string cause;
  std::vector<int> cols;
};

// Cross-validated RMS (bias-only base vs base + columns), fitting on even blocks and scoring on odd
// blocks and vice versa; OLS weighted by each log's noise variance.
void CrossValidate(const Design& d, const std::vector<double>& log_var, const MatrixXd& x_cause, int blocks,
                   double* rms_before, double* rms_after) {
  const int l = static_cast<int>(d.bins.size());
  std::vector<int> fold(d.n);
  VectorXd wt(d.n);
  for (int r = 0; r < l; ++r) {
    const int m = static_cast<int>(d.bins[r].t_s.size());
    for (int k = 0; k < m; ++k) {
      fold[d.offset[r] + k] = (k * blocks / m) % 2;
      wt(d.offset[r] + k) = 1 / std::sqrt(log_var[r]);
    }
  }
  std::vector<double> ss_before(l, 0), ss_after(l, 0), count(l, 0);
  std::vector<int> log_of(d.n);
  for (int r = 0; r < l; ++r) {
    for (size_t k = 0; k < d.bins[r].t_s.size(); ++k) log_of[d.offset[r] + k] = r;
  }
  for (int f = 0; f < 2; ++f) {
    std::vector<int> train, test;
    for (int i = 0; i < d.n; ++i) (fold[i] == f ? train : test).push_back(i);
    auto fit_score = [&](const MatrixXd& x, std::vector<double>* ss) {
      MatrixXd xt(train.size(), x.cols());
      VectorXd yt(train.size());
      for (size_t i = 0; i < train.size(); ++i) {
        xt.row(i) = x.row(train[i]) * wt(train[i]);
        yt(i) = d.y(train[i]) * wt(train[i]);
      }
      const LsFit fit = SolveLs(xt, yt);
      for (int i : test) {
        const double e = d.y(i) - x.row(i).dot(fit.beta);
        (*ss)[log_of[i]] += e * e;
      }
    };
    fit_score(d.base, &ss_before);
    fit_score(x_cause, &ss_after);
    for (int i : test) count[log_of[i]] += 1;
  }
  // The log where the cause explains most (in units of that log's noise variance) carries the
  // figure: pooling logs of very different noise would dilute it.
  int best = 0;
  for (int r = 1; r < l; ++r) {
    if ((ss_before[r] - ss_after[r]) / log_var[r] > (ss_before[best] - ss_after[best]) / log_var[best]) best = r;
  }
  *rms_before = std::sqrt(ss_before[best] / count[best]);
  *rms_after = std::sqrt(ss_after[best] / count[best]);
}

void Fail(const std::string& what) { throw InputError("options", what); }

}  // namespace

void GyroDiscoverOptions::Check() const {
  if (!(alpha > 0 && alpha < 0.5)) Fail("alpha must be in (0, 0.5)");
  if (max_bins_per_log < 50) Fail("max_bins_per_log must be >= 50");
  if (max_noise_lag < 2) Fail("max_noise_lag must be >= 2");
  if (!(wander_tau_max_s > 0)) Fail("wander_tau_max_s must be > 0");
  if (cv_blocks < 2) Fail("cv_blocks must be >= 2");
  rate.Check();
}

void CheckGyroBenchLog(const GyroBenchLog& log) {
  const size_t n = log.t_s.size();
  if (n < 50) throw InputError(log.file, "too few rows (" + std::to_string(n) + ", need >= 50)");
  auto same = [&](const std::vector<double>& v, const char* name) {
    if (v.size() != n) throw InputError(log.file, std::string("column ") + name + " has a different length");
    for (size_t i = 0; i < n; ++i) {
      if (!std::isfinite(v[i])) {
        throw InputError(log.file, std::string("column ") + name + " row " + std::to_string(i + 1) + ": not a finite number");
      }
    }
  };
  same(log.t_s, "t_s");
  same(log.w_dph, "w_dph");
  same(log.ref_dph, "ref_dph");
  same(log.temp_c, "temp_c");
  if (!log.azimuth_deg.empty()) same(log.azimuth_deg, "azimuth_deg");
  for (size_t i = 1; i < n; ++i) {
    if (!(log.t_s[i] > log.t_s[i - 1])) {
      throw InputError(log.file, "column t_s row " + std::to_string(i + 1) + ": time does not increase");
    }
  }
}

GyroBenchLog ReadGyroBenchLog(const std::string& path) {
  const CsvTable t = ReadCsv(path);
  GyroBenchLog log;
  log.file = path;
  log.t_s = t.Column("t_s");
  log.w_dph = t.Column("w_dph");
  log.ref_dph = t.Column("ref_dph");
  log.temp_c = t.Column("temp_c");
  if (t.Has("azimuth_deg")) log.azimuth_deg = t.Column("azimuth_deg");
  CheckGyroBenchLog(log);
  return log;
}

GyroDiscovery DiscoverGyro(const std::vector<GyroBenchLog>& logs, const GyroDiscoverOptions& o) {
  o.Check();
  if (logs.empty()) throw InputError("", "no gyro log given");
  Design d;
  for (const auto& log : logs) {
    CheckGyroBenchLog(log);
    d.offset.push_back(d.n);
    d.bins.push_back(MakeLogBins(log, o));
    d.n += static_cast<int>(d.bins.back().t_s.size());
  }
  const int l = static_cast<int>(logs.size());
  if (d.n < 40 + l) throw InputError(logs.front().file, "too few bins (" + std::to_string(d.n) + ") for discovery");
  d.cols.resize(d.n, kNumCols);
  d.y.resize(d.n);
  d.base = MatrixXd::Zero(d.n, l);
  for (int r = 0; r < l; ++r) {
    const auto& b = d.bins[r];
    for (size_t k = 0; k < b.t_s.size(); ++k) {
      const int i = d.offset[r] + static_cast<int>(k);
      d.y(i) = b.y_dph[k];
      for (int c = 0; c < kNumCols; ++c) d.cols(i, c) = b.x[k][c];
      d.base(i, r) = 1;
    }
  }
  // Applicability: a column is usable when it is not (nearly) a per-log constant. Regressors are
  // standardised (scaled to unit RMS after removing per-log means) for conditioning.
  std::vector<bool> usable(kNumCols, false);
  std::vector<double> scale(kNumCols, 1.0);
  for (int c = 0; c < kNumCols; ++c) {
    double ss = 0, ss_raw = 0;
    for (int r = 0; r < l; ++r) {
      const int m = static_cast<int>(d.bins[r].t_s.size());
      const VectorXd v = d.cols.col(c).segment(d.offset[r], m);
      ss += (v.array() - v.mean()).square().sum();
      ss_raw += v.squaredNorm();
    }
    usable[c] = ss > 1e-10 * std::max(ss_raw, 1e-300) && ss > 0;
    if (usable[c]) scale[c] = std::sqrt(ss / d.n);
    d.cols.col(c) /= scale[c];
  }
  std::vector<int> full_cols;
  for (int c = 0; c < kNumCols; ++c) {
    if (usable[c] && c != kMis) full_cols.push_back(c);  // misalignment is nested in the harmonic
  }
  if (!usable[kMagSin] && usable[kMis]) full_cols.push_back(kMis);

  // Two passes: the step of the `bias` candidate is located with the noise model of the full
  // model, then added to the full model (so that a step does not inflate the fitted wander) and
  // the noise model, the GLS and the scan are redone.
  GyroDiscovery res;
  res.n_bins = d.n;
  MatrixXd x_full, bw;
  std::vector<NoiseModel> nm;
  std::vector<double> log_var;
  VectorXd yw, base_res;
  LsFit full, base;
  double sigma2 = 1, f = 1;
  VectorXd best_step;
  double best_step_t = 0, best_w = 0;
  int positions = 0;
  for (int pass = 0; pass < 2; ++pass) {
    // 1. OLS of the full model -> per-log noise model.
    std::vector<VectorXd> extra;
    if (pass == 1 && best_step.size() == d.n) extra.push_back(best_step);
    x_full = Assemble(d, full_cols, extra);
    const LsFit ols = SolveLs(x_full, d.y);
    if (!ols.ok) throw InputError(logs.front().file, "degenerate regressors");
    const VectorXd e_ols = d.y - x_full * ols.beta;
    nm.clear();
    log_var.clear();
    for (int r = 0; r < l; ++r) {
      const int m = static_cast<int>(d.bins[r].t_s.size());
      const double phi_max = std::exp(-d.bins[r].bin_s / o.wander_tau_max_s);
      nm.push_back(FitNoise(e_ols.segment(d.offset[r], m), o.max_noise_lag, phi_max));
      log_var.push_back(nm.back().var_w + nm.back().var_g);
    }
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
    // Step scan: a step in one log's bias at a bin boundary (5 %..95 % of the log).
    best_w = 0;
    positions = 0;
    for (int r = 0; r < l; ++r) {
      const int m = static_cast<int>(d.bins[r].t_s.size());
      const VectorXd cw = bw.col(r).segment(d.offset[r], m);
      const VectorXd rr = base_res.segment(d.offset[r], m);
      for (int j = std::max(1, m / 20); j < m - m / 20; ++j) {
        VectorXd st = VectorXd::Zero(m);
        st.tail(m - j).setOnes();
        VectorXd sw = nm[r].Whiten(st);
        sw -= (cw.dot(sw) / cw.squaredNorm()) * cw;
        const double ss = sw.squaredNorm();
        if (ss <= 0) continue;
        ++positions;
        const double proj = rr.dot(sw);
        const double w = proj * proj / ss / (sigma2 * f);
        if (w > best_w) {
          best_w = w;
          best_step = VectorXd::Zero(d.n);
          best_step.segment(d.offset[r] + j, m - j).setOnes();
          best_step_t = 0.5 * (d.bins[r].t_s[j - 1] + d.bins[r].t_s[j]);
        }
      }
    }
  }
  res.variance_inflation = f;
  res.n_eff = d.n / f;
  {  // evidence: noise of the longest log
    int best = 0;
    for (int r = 1; r < l; ++r) {
      if (d.bins[r].t_s.size() * d.bins[r].bin_s > d.bins[best].t_s.size() * d.bins[best].bin_s) best = r;
    }
    res.noise_white_dph = std::sqrt(nm[best].var_w);
    res.noise_wander_dph = std::sqrt(nm[best].var_g);
    res.noise_wander_tau_s = nm[best].phi > 0 ? -d.bins[best].bin_s / std::log(nm[best].phi) : 0.0;
  }

  // 3. Candidates.
  const std::vector<CandidateSpec> specs = {
      {"temperature", {kT1, kT2}},   {"temperature_gradient", {kG1}}, {"magnetic_field", {kMagSin, kMagCos}},
      {"misalignment", {kMis}},      {"scale_factor", {kScale}},      {"time_delay", {kDelay}},
  };
  int tested = 2;  // bias and rate_random_walk are always tested
  for (const auto& s : specs) {
    bool ok = true;
    for (int c : s.cols) ok = ok && usable[c];
    tested += ok;
  }
  const double alpha_each = o.alpha / tested;
  res.alpha_per_candidate = alpha_each;
  struct Fitted {
    LsFit gls;
    MatrixXd x;  // raw (unwhitened) design of base + cause
    double inflation = 1;
  };
  std::map<std::string, Fitted> fits;
  // Every deterministic candidate and the located step against the base model, with GLS under
  // the per-log noise models `noise` and the inflation of the full model's whitened residuals.
  auto test_all = [&](const std::vector<NoiseModel>& noise) {
    std::vector<GyroCandidate> out;
    const VectorXd y_w = WhitenRows(d, noise, d.y);
    const MatrixXd xf_w = WhitenRows(d, noise, x_full);
    const LsFit fl = SolveLs(xf_w, y_w);
    const double s2 = fl.rss / std::max(1, d.n - static_cast<int>(x_full.cols()));
    const double infl = VarianceInflation(d, y_w - xf_w * fl.beta, o.max_noise_lag);
    const double n_eff = d.n / infl;
    const LsFit b0 = SolveLs(WhitenRows(d, noise, d.base), y_w);
    auto score = [&](GyroCandidate* c, const MatrixXd& x, double extra_cost) {
      const LsFit g = SolveLs(WhitenRows(d, noise, x), y_w);
      c->statistic = std::max(0.0, (b0.rss - g.rss) / (s2 * infl));
      c->delta_bic = d.n * std::log(b0.rss / g.rss) / infl - c->dof * std::log(n_eff) - extra_cost;
      fits[c->cause] = {g, x, infl};
    };
    for (const auto& sp : specs) {
      GyroCandidate c;
      c.cause = sp.cause;
      c.dof = static_cast<int>(sp.cols.size());
      for (int col : sp.cols) c.applicable = c.applicable && usable[col];
      if (c.applicable) {
        score(&c, Assemble(d, sp.cols, {}), 0.0);
        c.p_value = ChiSquaredSurvival(c.statistic, c.dof);
        c.significant = c.p_value < alpha_each;
      }
      out.push_back(c);
    }
    GyroCandidate c;  // bias: the scanned step, Bonferroni-corrected for the positions tried
    c.cause = "bias";
    c.dof = 1;
    c.applicable = best_step.size() == d.n;
    if (c.applicable) {
      score(&c, Assemble(d, {}, {best_step}), std::log(std::max(positions, 1)));  // the position costs too
      c.p_value = std::min(1.0, positions * ChiSquaredSurvival(c.statistic, 1));
      c.significant = c.p_value < alpha_each;
    }
    out.push_back(c);
    return out;
  };
  res.candidates = test_all(nm);

  // rate_random_walk: likelihood ratio of the noise model with a random walk of the bias against
  // the base noise model (white + Gauss-Markov wander with tau <= wander_tau_max_s), both by
  // maximum likelihood on each log's full-model residuals. q = 0 lies on the boundary, so the LR
  // follows 0.5 chi2_0 + 0.5 chi2_1 (Self & Liang 1987).
  std::vector<NoiseModel> nm_walk = nm;
  double walk_lnq_sigma = 1, walk_nll = 0;
  int walk_log = 0;
  {
    GyroCandidate c;
    c.cause = "rate_random_walk";
    c.dof = 1;
    // On the base-model residuals: the slow regressors of the full model would absorb most of a
    // walk. A deterministic cause then shows here too; it is sorted out by the re-test below.
    double p_min = 1;
    for (int r = 0; r < l; ++r) {
      const int m = static_cast<int>(d.bins[r].t_s.size());
      VectorXd v = d.y.segment(d.offset[r], m);
      v.array() -= v.mean();
      const NoiseMle h0 = FitNoiseMle(v, d.bins[r].bin_s, o.wander_tau_max_s, nm[r], false);
      // The likelihood is flat in ln q near q = 0: start from several walk strengths.
      NoiseMle h1;
      h1.nll = std::numeric_limits<double>::infinity();
      for (double rel : {1e-5, 1e-3, 1e-2, 1e-1}) {
        NoiseModel start = h0.model;
        start.q_rw = rel * (h0.model.var_w + h0.model.var_g);
        NoiseMle h = FitNoiseMle(v, d.bins[r].bin_s, o.wander_tau_max_s, start, true);
        if (h.nll < h1.nll) h1 = h;
      }
      const double lr = std::max(0.0, 2 * (h0.nll - h1.nll));
      walk_nll += h1.nll;
      const double p = std::min(1.0, l * 0.5 * ChiSquaredSurvival(lr, 1));
      nm_walk[r] = h1.model;
      nm_walk[r].diffuse_level = false;
      nm_walk[r].Prepare(m);
      if (p < p_min || r == 0) {
        p_min = p;
        c.statistic = lr;
        walk_lnq_sigma = h1.ln_q_sigma;
        walk_log = r;
      }
    }
    c.p_value = p_min;
    c.significant = p_min < alpha_each;
    c.delta_bic = c.statistic - std::log(res.n_eff);
    res.candidates.push_back(c);
  }
  // 4. Decision among the significant candidates: the smallest BIC of the exact likelihood
  // (noise model refitted by maximum likelihood on each log's residual), so that a deterministic
  // cause and a random walk, or a step and a walk, compete on the same footing.
  const GyroCandidate* chosen = nullptr;
  double chosen_bic = std::numeric_limits<double>::infinity();
  for (auto& c : res.candidates) {
    if (!c.applicable || !c.significant) continue;
    double bic = 0;
    if (c.cause == "rate_random_walk") {
      bic = 2 * walk_nll + 4.0 * l * std::log(static_cast<double>(d.n));
    } else {
      const Fitted& ft = fits[c.cause];
      const LsFit g = SolveLs(WhitenRows(d, nm, ft.x), WhitenRows(d, nm, d.y));
      const VectorXd e = d.y - ft.x * g.beta;
      for (int r = 0; r < l; ++r) {
        const int m = static_cast<int>(d.bins[r].t_s.size());
        bic += 2 * FitNoiseMle(e.segment(d.offset[r], m), d.bins[r].bin_s, o.wander_tau_max_s, nm[r], false).nll;
      }
      bic += (3.0 * l + c.dof) * std::log(static_cast<double>(d.n));
      if (c.cause == "bias") bic += 2 * std::log(std::max(positions, 1));
    }
    c.bic = bic;
    if (bic < chosen_bic) chosen_bic = bic, chosen = &c;
  }
  // misalignment is nested in magnetic_field (a harmonic of fixed phase): the free phase is kept
  // when its extra term is itself significant (chi^2_1 at alpha, a follow-up test).
  if (chosen && chosen->cause == "misalignment") {
    for (const auto& c : res.candidates) {
      if (c.cause == "magnetic_field" && c.significant &&
          ChiSquaredSurvival(c.statistic - chosen->statistic, 1) < o.alpha) {
        chosen = &c;
        break;
      }
    }
  }
  if (!chosen) {
    res.cause = "none";
    CrossValidate(d, log_var, d.base, o.cv_blocks, &res.rms_before_dph, &res.rms_after_dph);
    res.rms_after_dph = res.rms_before_dph;
    res.gain = 1;
    return res;
  }
  res.cause = chosen->cause;

  // 5. Parameters (GLS, sigma scaled by the residual variance and the inflation).
  if (res.cause != "rate_random_walk") {
    const Fitted& fit = fits[res.cause];
    const LsFit& g = fit.gls;
    const int dof_res = std::max(1, d.n - static_cast<int>(fit.x.cols()));
    const double s2 = g.rss / dof_res * fit.inflation;
    auto est = [&](int j, double unscale) { return std::pair<double, double>{g.beta(l + j) / unscale, std::sqrt(g.cov_unscaled(l + j, l + j) * s2) / unscale}; };
    if (res.cause == "temperature") {
      auto [a, sa] = est(0, scale[kT1]);
      auto [b, sb] = est(1, scale[kT2]);
      res.parameters["K10_dph"] = a, res.sigmas["K10_dph"] = sa;
      res.parameters["K20_dph"] = b, res.sigmas["K20_dph"] = sb;
    } else if (res.cause == "temperature_gradient") {
      auto [a, sa] = est(0, scale[kG1]);
      res.parameters["K01_dph"] = a, res.sigmas["K01_dph"] = sa;
    } else if (res.cause == "magnetic_field") {
      // f = e_sin sin(psi) + e_cos cos(psi) = S sin(psi + phi): S cos(phi) = e_sin, S sin(phi) = e_cos.
      const double es = g.beta(l) / scale[kMagSin], ec = g.beta(l + 1) / scale[kMagCos];
      Eigen::Matrix2d cov;
      cov << g.cov_unscaled(l, l) / (scale[kMagSin] * scale[kMagSin]),
          g.cov_unscaled(l, l + 1) / (scale[kMagSin] * scale[kMagCos]),
          g.cov_unscaled(l + 1, l) / (scale[kMagSin] * scale[kMagCos]),
          g.cov_unscaled(l + 1, l + 1) / (scale[kMagCos] * scale[kMagCos]);
      cov *= s2;
      const double amp = std::hypot(es, ec);
      const Eigen::Vector2d da(es / amp, ec / amp), dp(-ec / (amp * amp), es / (amp * amp));
      res.parameters["amplitude_dph"] = amp;
      res.sigmas["amplitude_dph"] = std::sqrt(da.dot(cov * da));
      res.parameters["phase_deg"] = std::atan2(ec, es) * kRadToDeg;
      res.sigmas["phase_deg"] = std::sqrt(dp.dot(cov * dp)) * kRadToDeg;
    } else if (res.cause == "misalignment") {
      auto [a, sa] = est(0, scale[kMis]);
      res.parameters["misalignment_arcsec"] = a, res.sigmas["misalignment_arcsec"] = sa;
    } else if (res.cause == "scale_factor") {
      auto [a, sa] = est(0, scale[kScale]);
      res.parameters["scale_factor_ppm"] = a, res.sigmas["scale_factor_ppm"] = sa;
    } else if (res.cause == "time_delay") {
      auto [a, sa] = est(0, scale[kDelay]);
      res.parameters["delay_s"] = a, res.sigmas["delay_s"] = sa;
    } else if (res.cause == "bias") {
      auto [a, sa] = est(0, 1.0);
      res.parameters["step_dph"] = a, res.sigmas["step_dph"] = sa;
      res.parameters["step_time_s"] = best_step_t;
      res.sigmas["step_time_s"] = d.bins[0].bin_s;
    }
    CrossValidate(d, log_var, fit.x, o.cv_blocks, &res.rms_before_dph, &res.rms_after_dph);
  } else {
    // K from the walk's variance per bin: q = K^2 bin (K in dph/sqrt(s)).
    const double q = nm_walk[walk_log].q_rw, bin = d.bins[walk_log].bin_s;
    const double k_dph_sqrt_h = std::sqrt(q / bin) * 60.0;
    res.parameters["K_dph_per_sqrt_h"] = k_dph_sqrt_h;
    res.sigmas["K_dph_per_sqrt_h"] = 0.5 * k_dph_sqrt_h * walk_lnq_sigma;
    // Held-out one-step prediction of the second half's bins: constant bias (base) vs an
    // exponentially smoothed level with its factor tuned on the first half (local-level model).
    double best_ratio = -1;
    for (int rr = 0; rr < l; ++rr) {
      const int mm = static_cast<int>(d.bins[rr].t_s.size());
      const VectorXd z = d.y.segment(d.offset[rr], mm);
      const int half = mm / 2;
      auto one_step = [&](double a, int from, int to, double level) {
        double ss = 0;
        for (int i = from; i < to; ++i) {
          const double e2 = z(i) - level;
          ss += e2 * e2;
          level += a * e2;
        }
        return ss;
      };
      double best_a = 0, best_ss = std::numeric_limits<double>::infinity();
      for (double a = 0.002; a <= 0.5; a *= 1.25) {
        const double ss = one_step(a, 1, half, z(0));
        if (ss < best_ss) best_ss = ss, best_a = a;
      }
      const double mean_first = z.head(half).mean();
      double level = z(0);
      for (int i = 1; i < half; ++i) level += best_a * (z(i) - level);
      const double sb = one_step(0.0, half, mm, mean_first), sa = one_step(best_a, half, mm, level);
      if (sb / sa > best_ratio) {  // the log where the level model predicts best carries the figure
        best_ratio = sb / sa;
        res.rms_before_dph = std::sqrt(sb / (mm - half));
        res.rms_after_dph = std::sqrt(sa / (mm - half));
      }
    }
  }
  res.gain = res.rms_after_dph > 0 ? res.rms_before_dph / res.rms_after_dph : 1.0;
  return res;
}

Json GyroDiscoveryToJson(const GyroDiscovery& d) {
  Json j;
  j["cause"] = d.cause;
  j["parameters"] = Json::object();
  for (const auto& [k, v] : d.parameters) j["parameters"][k] = v;
  j["parameter_sigmas"] = Json::object();
  for (const auto& [k, v] : d.sigmas) j["parameter_sigmas"][k] = v;
  j["rms_before_dph"] = d.rms_before_dph;
  j["rms_after_dph"] = d.rms_after_dph;
  j["gain"] = d.gain;
  j["gain_method"] = d.cause == "rate_random_walk" ? "held-out one-step prediction (second half of each log)"
                                                   : "cross-validation on interleaved blocks";
  j["evidence"] = {{"n_bins", d.n_bins},
                   {"n_eff", d.n_eff},
                   {"variance_inflation", d.variance_inflation},
                   {"noise_white_dph", d.noise_white_dph},
                   {"noise_wander_dph", d.noise_wander_dph},
                   {"noise_wander_tau_s", d.noise_wander_tau_s},
                   {"alpha_per_candidate", d.alpha_per_candidate}};
  j["candidates"] = Json::array();
  for (const auto& c : d.candidates) {
    Json cj = {{"cause", c.cause}, {"applicable", c.applicable}};
    if (c.applicable) {
      cj["statistic"] = c.statistic;
      cj["p_value"] = c.p_value;
      cj["delta_bic"] = c.delta_bic;
      cj["significant"] = c.significant;
      if (c.significant) cj["likelihood_bic"] = c.bic;
    }
    j["candidates"].push_back(cj);
  }
  return j;
}

}  // namespace ssiu
