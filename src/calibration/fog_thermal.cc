#include "calibration/fog_thermal.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/csv.h"
#include "core/error.h"
#include "core/stats.h"
#include "sim/fog_bench_sim.h"

namespace ssiu {
namespace {

constexpr int kTerms = ThermalDriftModel::kNumTerms;
constexpr int kSubsets = 1 << kTerms;

using Eigen::MatrixXd;
using Eigen::VectorXd;

// Binned data of one run.
struct Bins {
  std::vector<double> t_s, y_dph, temp_c, rate_c_per_min, dt_s;
  MatrixXd x;  // n x 10 regressors
};

Bins MakeBins(const ThermalRun& run, double bin_s, const TemperatureRateOptions& rate) {
  Bins b;
  const double t0 = run.t_s.front();
  std::vector<double> sum_t, sum_y;
  std::vector<int> count;
  for (size_t i = 0; i < run.t_s.size(); ++i) {
    const size_t k = static_cast<size_t>((run.t_s[i] - t0) / bin_s);
    if (k >= count.size()) {
      sum_t.resize(k + 1, 0.0);
      sum_y.resize(k + 1, 0.0);
      count.resize(k + 1, 0);
    }
    sum_t[k] += run.t_s[i];
    sum_y[k] += run.w_dph[i] - run.ref_dph[i];
    ++count[k];
  }
  // Keep bins with at least half the typical count (drops a short last bin and gaps).
  std::vector<int> sorted = count;
  std::sort(sorted.begin(), sorted.end());
  const int typical = sorted[sorted.size() / 2];
  double prev_t = t0;
  for (size_t k = 0; k < count.size(); ++k) {
    if (count[k] == 0 || 2 * count[k] < typical) continue;
    const double t = sum_t[k] / count[k];
    b.t_s.push_back(t);
    b.y_dph.push_back(sum_y[k] / count[k]);
    b.dt_s.push_back(t - prev_t);
    prev_t = t;
  }
  const TemperatureEstimate te = EstimateTemperatureRate(run.t_s, run.temp_c, b.t_s, rate);
  b.temp_c = te.temp_c;
  b.rate_c_per_min = te.rate_c_per_min;
  const ThermalDriftModel unit;
  b.x.resize(b.t_s.size(), kTerms);
  for (size_t i = 0; i < b.t_s.size(); ++i) {
    const double z1 = unit.Z1(b.temp_c[i]), z2 = unit.Z2(b.rate_c_per_min[i]);
    for (int k = 0; k < kTerms; ++k) b.x(i, k) = ThermalDriftModel::Monomial(k, z1, z2);
  }
  return b;
}

std::vector<int> SubsetIndices(int mask) {
  std::vector<int> idx;
  for (int k = 0; k < kTerms; ++k) {
    if (mask & (1 << k)) idx.push_back(k);
  }
  return idx;
}

// Normal-equation moments of whitened data, per run, so that subsets and leave-one-run-out
// fits are O(p^3) each.
struct Moments {
  MatrixXd a = MatrixXd::Zero(kTerms, kTerms);
  VectorXd b = VectorXd::Zero(kTerms);
  double yy = 0;
  int n = 0;
  Moments& operator+=(const Moments& o) {
    a += o.a;
    b += o.b;
    yy += o.yy;
    n += o.n;
    return *this;
  }
};

struct SubsetFit {
  VectorXd beta;  // over the subset's indices
  MatrixXd a_inv;
  double rss = 0;
  bool ok = false;
};

SubsetFit SolveSubset(const Moments& m, const std::vector<int>& idx) {
  SubsetFit f;
  const int p = static_cast<int>(idx.size());
  if (p == 0) {
    f.rss = m.yy;
    f.ok = true;
    return f;
  }
  MatrixXd a(p, p);
  VectorXd b(p);
  for (int i = 0; i < p; ++i) {
    b(i) = m.b(idx[i]);
    for (int j = 0; j < p; ++j) a(i, j) = m.a(idx[i], idx[j]);
  }
  Eigen::LDLT<MatrixXd> ldlt(a);
  if (ldlt.info() != Eigen::Success || ldlt.vectorD().minCoeff() <= 1e-12 * ldlt.vectorD().maxCoeff()) {
    return f;
  }
  f.beta = ldlt.solve(b);
  f.a_inv = ldlt.solve(MatrixXd::Identity(p, p));
  f.rss = std::max(m.yy - b.dot(f.beta), 1e-300);
  f.ok = true;
  return f;
}

// Autocorrelation at `lag` pooled over runs (within runs only).
double AutoCorr(const std::vector<VectorXd>& series, int lag) {
  double num = 0, den = 0;
  for (const auto& e : series) {
    for (int i = 0; i < e.size(); ++i) {
      den += e(i) * e(i);
      if (i >= lag) num += e(i) * e(i - lag);
    }
  }
  return den > 0 ? num / den : 0.0;
}

DriftBand Band(const std::vector<double>& v) {
  DriftBand d;
  double ss = 0;
  for (double x : v) {
    d.peak_dph = std::max(d.peak_dph, std::abs(x));
    ss += x * x;
  }
  d.rms_dph = v.empty() ? 0 : std::sqrt(ss / v.size());
  return d;
}

void Fail(const std::string& what) { throw InputError("options", what); }

}  // namespace

void TemperatureRateOptions::Check() const {
  if (!(window_s > 0)) Fail("rate window must be positive");
  if (order < 1 || order > 5) Fail("rate polynomial order must be 1..5");
}

void ThermalFitOptions::Check() const {
  if (!(bin_s > 0)) Fail("bin_s must be positive");
  rate.Check();
  if (max_noise_lag < 2) Fail("max_noise_lag must be >= 2");
  if (validate_top < 1) Fail("validate_top must be >= 1");
}

void CheckThermalRun(const ThermalRun& run) {
  const size_t n = run.t_s.size();
  if (run.w_dph.size() != n || run.ref_dph.size() != n || run.temp_c.size() != n) {
    throw InputError(run.file, "columns of different length");
  }
  if (n < 10) throw InputError(run.file, "too few rows (" + std::to_string(n) + ", need >= 10)");
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(run.t_s[i]) || !std::isfinite(run.w_dph[i]) || !std::isfinite(run.ref_dph[i]) ||
        !std::isfinite(run.temp_c[i])) {
      throw InputError(run.file, "row " + std::to_string(i + 1) + ": not a finite number");
    }
    if (i > 0 && !(run.t_s[i] > run.t_s[i - 1])) {
      throw InputError(run.file, "column 't_s' is not strictly increasing at row " + std::to_string(i + 1));
    }
  }
  // The bins span the run's time range: a gap of 1e12 s between two rows allocated terabytes. A gap
  // of more than 1000 median steps is two runs in one file.
  std::vector<double> dt(n - 1);
  for (size_t i = 1; i < n; ++i) dt[i - 1] = run.t_s[i] - run.t_s[i - 1];
  const double median = Median(std::move(dt));
  for (size_t i = 1; i < n; ++i) {
    if (run.t_s[i] - run.t_s[i - 1] > 1000 * median) {
      throw InputError(run.file, "column 't_s': gap of " + std::to_string(run.t_s[i] - run.t_s[i - 1]) + " s at row " +
                                     std::to_string(i + 1) + " (median step " + std::to_string(median) +
                                     " s): give the parts as separate runs");
    }
  }
}

ThermalRun ReadThermalRun(const std::string& path, double latitude_deg, const std::string& axis) {
  const CsvTable csv = ReadCsv(path);
  ThermalRun run;
  run.file = path;
  run.t_s = csv.Column("t_s");
  csv.CheckIncreasing("t_s");
  run.w_dph = csv.Column("w_dph");
  run.temp_c = csv.Column("temp_c");
  if (csv.Has("ref_dph")) {
    run.ref_dph = csv.Column("ref_dph");
  } else if (std::isfinite(latitude_deg)) {
    run.ref_dph.assign(run.t_s.size(), EarthRateOnAxisDph(latitude_deg, axis));
  } else {
    throw InputError(path, "missing column 'ref_dph' (or give --latitude-deg and --axis)");
  }
  CheckThermalRun(run);
  return run;
}

TemperatureEstimate EstimateTemperatureRate(const std::vector<double>& t_s, const std::vector<double>& temp_c,
                                            const std::vector<double>& at_s, const TemperatureRateOptions& o) {
  o.Check();
  TemperatureEstimate out;
  out.temp_c.resize(at_s.size());
  out.rate_c_per_min.resize(at_s.size());
  const double half = 0.5 * o.window_s;
  const int p = o.order + 1;
  size_t lo = 0, hi = 0;  // window [lo, hi) for sorted query times
  for (size_t q = 0; q < at_s.size(); ++q) {
    const double tc = at_s[q];
    if (q > 0 && tc < at_s[q - 1]) lo = hi = 0;  // unsorted queries: restart the scan
    while (lo < t_s.size() && t_s[lo] < tc - half) ++lo;
    if (hi < lo) hi = lo;
    while (hi < t_s.size() && t_s[hi] <= tc + half) ++hi;
    if (static_cast<int>(hi - lo) < p + 2) {
      throw InputError("temp_c", "too few temperature samples within the " + std::to_string(o.window_s) +
                                     " s rate window at t = " + std::to_string(tc) + " s");
    }
    // Local polynomial in u = (t - tc)/half (Savitzky-Golay for irregular samples): the value and
    // slope at u = 0 are c0 and c1/half.
    // The normal matrix is Hankel, a(r, c) = sum u^(r+c): its 2p - 1 sums are accumulated once.
    double pw[12] = {}, mom[12] = {}, by[12] = {};  // plain arrays: std::array's [] is a call in the sanitizer build
    for (size_t i = lo; i < hi; ++i) {
      const double u = (t_s[i] - tc) / half;
      double m = 1;
      for (int k = 0; k < 2 * p - 1; ++k) {
        pw[k] = m;
        mom[k] += m;
        m *= u;
      }
      for (int r = 0; r < p; ++r) by[r] += temp_c[i] * pw[r];
    }
    // At most 6 x 6 (order <= 5): on the stack, not a heap allocation a query.
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6> a(p, p);
    Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1> b(p);
    for (int r = 0; r < p; ++r) {
      b(r) = by[r];
      for (int c = 0; c < p; ++c) a(r, c) = mom[r + c];
    }
    const Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1> c = a.ldlt().solve(b);
    out.temp_c[q] = c(0);
    out.rate_c_per_min[q] = c(1) / half * 60.0;
  }
  return out;
}

ThermalEvaluation EvaluateThermalModel(const std::vector<ThermalRun>& runs, const ThermalDriftModel& model,
                                       const ThermalFitOptions& options) {
  options.Check();
  ThermalEvaluation ev;
  std::vector<double> all_before, all_after;
  for (const auto& run : runs) {
    CheckThermalRun(run);
    const Bins b = MakeBins(run, options.bin_s, options.rate);
    ThermalRunSeries s;
    s.file = run.file;
    double ang_b = 0, ang_a = 0;
    for (size_t i = 0; i < b.t_s.size(); ++i) {
      const double m = model.DriftDph(b.temp_c[i], b.rate_c_per_min[i]);
      s.t_min.push_back((b.t_s[i] - run.t_s.front()) / 60.0);
      s.temp_c.push_back(b.temp_c[i]);
      s.rate_c_per_min.push_back(b.rate_c_per_min[i]);
      s.drift_before_dph.push_back(b.y_dph[i]);
      s.drift_after_dph.push_back(b.y_dph[i] - m);
      // Accumulated angle: integral of the drift (deg/h * h).
      ang_b += b.y_dph[i] * b.dt_s[i] / 3600.0;
      ang_a += (b.y_dph[i] - m) * b.dt_s[i] / 3600.0;
      s.angle_before_deg.push_back(ang_b);
      s.angle_after_deg.push_back(ang_a);
      ev.angle_error_before_deg = std::max(ev.angle_error_before_deg, std::abs(ang_b));
      ev.angle_error_after_deg = std::max(ev.angle_error_after_deg, std::abs(ang_a));
    }
    all_before.insert(all_before.end(), s.drift_before_dph.begin(), s.drift_before_dph.end());
    all_after.insert(all_after.end(), s.drift_after_dph.begin(), s.drift_after_dph.end());
    ev.runs.push_back(std::move(s));
  }
  ev.before = Band(all_before);
  ev.after = Band(all_after);
  ev.gain = ev.after.peak_dph > 0 ? ev.before.peak_dph / ev.after.peak_dph : 0.0;
  return ev;
}

namespace {

// The runs binned, with the total number of bins (at least four per term).
std::vector<Bins> BinRuns(const std::vector<ThermalRun>& runs, const ThermalFitOptions& options, int* n_out) {
  std::vector<Bins> bins;
  int n = 0;
  for (const auto& run : runs) {
    CheckThermalRun(run);
    bins.push_back(MakeBins(run, options.bin_s, options.rate));
    n += static_cast<int>(bins.back().t_s.size());
  }
  if (n < 4 * kTerms) {
    throw InputError(runs.front().file, "too few " + std::to_string(options.bin_s) + " s bins (" + std::to_string(n) +
                                            ", need >= " + std::to_string(4 * kTerms) + ")");
  }
  *n_out = n;
  return bins;
}

// Ordinary least squares with all ten terms: its residuals estimate the noise whatever the true
// subset is (every subset is nested in it).
VectorXd FullOlsResiduals(const std::vector<Bins>& bins, int n) {
  MatrixXd x_all(n, kTerms);
  VectorXd y_all(n);
  int r = 0;
  for (const auto& b : bins) {
    x_all.middleRows(r, b.x.rows()) = b.x;
    y_all.segment(r, b.x.rows()) = Eigen::Map<const VectorXd>(b.y_dph.data(), b.y_dph.size());
    r += static_cast<int>(b.x.rows());
  }
  const VectorXd beta_ols = x_all.colPivHouseholderQr().solve(y_all);
  return y_all - x_all * beta_ols;
}

// The residual noise per bin: white (var_w) plus Gauss-Markov (var_g, correlation phi per bin).
struct BinNoise {
  double gamma0 = 0;  // the residuals' variance
  double var_w = 0, var_g = 0, phi = 0;
};

// gamma_0 = s_w^2 + s_g^2, gamma_k = s_g^2 phi^k (k >= 1), white + Gauss-Markov (an ARMA(1,1)
// autocovariance); phi and s_g^2 from a log-linear fit over the positive lags.
BinNoise FitBinNoise(const std::vector<Bins>& bins, const VectorXd& e_ols, const ThermalFitOptions& options) {
  std::vector<double> gamma(options.max_noise_lag + 1, 0.0);
  std::vector<int> gcount(options.max_noise_lag + 1, 0);
  int r = 0;
  for (const auto& b : bins) {
    const int m = static_cast<int>(b.x.rows());
    for (int k = 0; k <= options.max_noise_lag; ++k) {
      for (int i = k; i < m; ++i) {
        gamma[k] += e_ols(r + i) * e_ols(r + i - k);
        ++gcount[k];
      }
    }
    r += m;
  }
  for (int k = 0; k <= options.max_noise_lag; ++k) gamma[k] = gcount[k] ? gamma[k] / gcount[k] : 0.0;
  BinNoise noise;
  noise.gamma0 = gamma[0];
  noise.var_w = gamma[0];
  if (!(options.prewhiten && gamma[0] > 0 && gamma[1] > 0)) return noise;
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int m = 0;
  for (int k = 1; k <= options.max_noise_lag && gamma[k] > 0; ++k) {
    sx += k;
    sy += std::log(gamma[k]);
    sxx += k * k;
    sxy += k * std::log(gamma[k]);
    ++m;
  }
  double phi = 0, var_g = 0;
  if (m >= 2) {
    const double slope = (m * sxy - sx * sy) / (m * sxx - sx * sx);
    phi = std::exp(slope);
    var_g = std::exp((sy - slope * sx) / m);
  } else {  // one positive lag: plain AR(1)
    phi = gamma[1] / gamma[0];
    var_g = gamma[0];
  }
  noise.phi = std::clamp(phi, 0.0, 0.999);
  noise.var_g = std::clamp(var_g, 0.0, gamma[0]);
  noise.var_w = std::max(gamma[0] - noise.var_g, 1e-6 * gamma[0]);
  return noise;
}

// The runs' whitened data and their normal-equation moments.
struct WhitenedRuns {
  std::vector<Moments> moments;
  std::vector<MatrixXd> xw;
  std::vector<VectorXd> yw;
  Moments total;
};

// Sigma = s_w^2 I + s_g^2 phi^{|dt|/bin} per run (runs independent); with L L^T = Sigma, the whitened
// data L^-1 y, L^-1 X have (nearly) white residuals (GLS).
WhitenedRuns Prewhiten(const std::vector<Bins>& bins, const BinNoise& noise, double bin_s) {
  WhitenedRuns w;
  for (const auto& b : bins) {
    const int m = static_cast<int>(b.x.rows());
    MatrixXd xw = b.x;
    VectorXd yw = Eigen::Map<const VectorXd>(b.y_dph.data(), m);
    if (noise.var_g > 0) {
      MatrixXd sigma(m, m);
      for (int i = 0; i < m; ++i) {
        for (int j = 0; j < m; ++j) {
          sigma(i, j) =
              noise.var_g * std::pow(noise.phi, std::abs(b.t_s[i] - b.t_s[j]) / bin_s) + (i == j ? noise.var_w : 0.0);
        }
      }
      Eigen::LLT<MatrixXd> llt(sigma / noise.gamma0);
      if (llt.info() == Eigen::Success) {
        llt.matrixL().solveInPlace(xw);
        llt.matrixL().solveInPlace(yw);
      }
    }
    Moments mo;
    mo.a = xw.transpose() * xw;
    mo.b = xw.transpose() * yw;
    mo.yy = yw.squaredNorm();
    mo.n = m;
    w.moments.push_back(mo);
    w.xw.push_back(std::move(xw));
    w.yw.push_back(std::move(yw));
  }
  for (const auto& m : w.moments) w.total += m;
  return w;
}

// Correlation left in the whitened residuals of the full model -> res->whitened_r1 and the variance
// inflation 1 + 2 sum_k (1 - k/(L+1)) r_k (Bartlett-weighted integrated autocorrelation; (1 + r1)/(1 - r1)
// for an AR(1) remainder), which shrinks the sample size.
void MeasureVarianceInflation(const WhitenedRuns& w, const SubsetFit& full, const ThermalFitOptions& options,
                              ThermalFitResult* res) {
  std::vector<VectorXd> ew;
  for (size_t r = 0; r < w.xw.size(); ++r) ew.push_back(w.yw[r] - w.xw[r] * full.beta);
  res->whitened_r1 = AutoCorr(ew, 1);
  double f = 1;
  for (int k = 1; k <= options.max_noise_lag; ++k) {
    f += 2 * (1 - k / (options.max_noise_lag + 1.0)) * AutoCorr(ew, k);
  }
  res->variance_inflation = options.effective_sample_size ? std::clamp(f, 1.0, 20.0) : 1.0;
}

// BIC of all 1024 subsets (Schwarz 1978) with the effective sample size:
// BIC = (n_eff/n) * n ln(RSS/n) + k ln(n_eff); infinite for a degenerate subset.
std::vector<double> SubsetBics(const Moments& total, int n, double inflate, double n_eff) {
  std::vector<double> bic(kSubsets, std::numeric_limits<double>::infinity());
  for (int mask = 0; mask < kSubsets; ++mask) {
    const auto idx = SubsetIndices(mask);
    const SubsetFit f = SolveSubset(total, idx);
    if (!f.ok) continue;
    bic[mask] = n * std::log(f.rss / n) / inflate + idx.size() * std::log(n_eff);
  }
  return bic;
}

// The selected subset's terms and sigmas into res->model, and every term's statistics (selected, in
// the full model, the BIC change of toggling it) into res->tested.
void ReportTerms(const Moments& total, const SubsetFit& full, const std::vector<double>& bic, int best, int n,
                 ThermalFitResult* res) {
  const double inflate = res->variance_inflation;
  const auto best_idx = SubsetIndices(best);
  const SubsetFit sel = SolveSubset(total, best_idx);
  const double s2_sel = sel.rss / std::max(1, n - static_cast<int>(best_idx.size()));
  for (size_t i = 0; i < best_idx.size(); ++i) {
    const int k = best_idx[i];
    res->kept[k] = true;
    res->model.k_dph[k] = sel.beta(i);
    res->sigma_dph[k] = std::sqrt(s2_sel * sel.a_inv(i, i) * inflate);
  }
  const double s2_full = full.rss / (n - kTerms);
  for (int k = 0; k < kTerms; ++k) {
    ThermalTermStat st;
    st.name = ThermalDriftModel::TermName(k);
    st.kept = res->kept[k];
    st.estimate_dph = res->model.k_dph[k];
    st.sigma_dph = res->sigma_dph[k];
    st.full_estimate_dph = full.beta(k);
    st.full_sigma_dph = std::sqrt(s2_full * full.a_inv(k, k) * inflate);
    st.full_t = st.full_estimate_dph / st.full_sigma_dph;
    st.delta_bic_toggle = bic[best ^ (1 << k)] - bic[best];
    res->tested.push_back(st);
  }
}

// Leave one run out: the subset fitted (GLS) on the other runs, the RMS of the un-whitened residual
// drift of the left-out run, pooled over the runs; negative when no run could be predicted.
double LeaveOneRunOutRms(const std::vector<Bins>& bins, const std::vector<Moments>& moments,
                         const std::vector<int>& idx) {
  double ss = 0;
  int cnt = 0;
  for (size_t h = 0; h < bins.size(); ++h) {
    Moments train;
    for (size_t r = 0; r < bins.size(); ++r) {
      if (r != h) train += moments[r];
    }
    const SubsetFit f = SolveSubset(train, idx);
    if (!f.ok) continue;
    for (int i = 0; i < bins[h].x.rows(); ++i) {
      double pred = 0;
      for (size_t j = 0; j < idx.size(); ++j) pred += f.beta(j) * bins[h].x(i, idx[j]);
      const double e = bins[h].y_dph[i] - pred;
      ss += e * e;
      ++cnt;
    }
  }
  return cnt > 0 ? std::sqrt(ss / cnt) : -1.0;
}

// Validation of the best candidates by BIC (leave one run out, with two runs or more) into
// res->candidates, res->validation_agrees and res->message.
void ValidateCandidates(const std::vector<Bins>& bins, const std::vector<Moments>& moments,
                        const std::vector<double>& bic, int best, int validate_top, ThermalFitResult* res) {
  std::vector<int> order(kSubsets);
  std::iota(order.begin(), order.end(), 0);
  const int top = std::min(validate_top, kSubsets);
  std::partial_sort(order.begin(), order.begin() + top, order.end(), [&](int a, int b) { return bic[a] < bic[b]; });
  double best_cv = std::numeric_limits<double>::infinity(), chosen_cv = -1;
  for (int c = 0; c < top; ++c) {
    const int mask = order[c];
    if (!std::isfinite(bic[mask])) break;
    ThermalCandidate cand;
    const auto idx = SubsetIndices(mask);
    for (int k : idx) cand.terms.push_back(ThermalDriftModel::TermName(k));
    cand.bic = bic[mask];
    if (bins.size() >= 2) {
      const double cv_rms_dph = LeaveOneRunOutRms(bins, moments, idx);
      if (cv_rms_dph >= 0) {
        cand.cv_rms_dph = cv_rms_dph;
        best_cv = std::min(best_cv, cand.cv_rms_dph);
        if (mask == best) chosen_cv = cand.cv_rms_dph;
      }
    }
    res->candidates.push_back(cand);
  }
  res->validation_agrees = chosen_cv < 0 || chosen_cv <= 1.05 * best_cv;
  res->message = bins.size() >= 2 ? (res->validation_agrees ? "BIC choice confirmed by leave-one-run-out validation"
                                                            : "another candidate validates better on held-out runs")
                                  : "single run: no held-out validation";
}

}  // namespace

ThermalFitResult FitThermalDrift(const std::vector<ThermalRun>& runs, const ThermalFitOptions& options) {
  options.Check();
  if (runs.empty()) throw InputError("", "no thermal run given");
  int n = 0;
  const std::vector<Bins> bins = BinRuns(runs, options, &n);
  ThermalFitResult res;
  res.status = FitStatus::kFitted;
  res.n_bins = n;

  // 1. The noise model, from the residuals of ordinary least squares with all ten terms.
  const BinNoise noise = FitBinNoise(bins, FullOlsResiduals(bins, n), options);
  res.noise_white_dph = std::sqrt(std::max(noise.var_w, 0.0));
  res.noise_wander_dph = std::sqrt(noise.var_g);
  res.noise_wander_tau_s = noise.phi > 0 && noise.phi < 1 ? -options.bin_s / std::log(noise.phi) : 0.0;

  // 2. Prewhitening by that model (GLS).
  const WhitenedRuns whitened = Prewhiten(bins, noise, options.bin_s);

  // 3. The full model's whitened residuals -> effective sample size.
  std::vector<int> all(kTerms);
  std::iota(all.begin(), all.end(), 0);
  const SubsetFit full = SolveSubset(whitened.total, all);
  if (!full.ok)
    throw InputError(runs.front().file, "the ten regressors are degenerate (temperature programme too poor)");
  MeasureVarianceInflation(whitened, full, options, &res);
  const double inflate = res.variance_inflation;
  const double n_eff = n / inflate;
  res.n_eff = n_eff;

  // 4. Term selection: all 1024 subsets by BIC.
  const std::vector<double> bic = SubsetBics(whitened.total, n, inflate, n_eff);
  const int best = static_cast<int>(std::min_element(bic.begin(), bic.end()) - bic.begin());
  ReportTerms(whitened.total, full, bic, best, n, &res);

  // 5. Validation of the best candidates on held-out runs, and the selected model's evaluation.
  ValidateCandidates(bins, whitened.moments, bic, best, options.validate_top, &res);
  res.evaluation = EvaluateThermalModel(runs, res.model, options);
  return res;
}

ThermalCompensation CompensateThermalRun(const ThermalRun& run, const ThermalDriftModel& model,
                                         const TemperatureRateOptions& rate) {
  CheckThermalRun(run);
  ThermalCompensation c;
  const TemperatureEstimate te = EstimateTemperatureRate(run.t_s, run.temp_c, run.t_s, rate);
  c.t_s = run.t_s;
  c.w_dph = run.w_dph;
  c.temp_c = te.temp_c;
  c.rate_c_per_min = te.rate_c_per_min;
  for (size_t i = 0; i < run.t_s.size(); ++i) {
    c.model_dph.push_back(model.DriftDph(te.temp_c[i], te.rate_c_per_min[i]));
    c.w_comp_dph.push_back(run.w_dph[i] - c.model_dph.back());
  }
  return c;
}

Json ThermalEvaluationToJson(const ThermalEvaluation& e) {
  Json j;
  j["drift_before_dph"] = {{"peak", e.before.peak_dph}, {"rms", e.before.rms_dph}};
  j["drift_after_dph"] = {{"peak", e.after.peak_dph}, {"rms", e.after.rms_dph}};
  j["angle_error_before_deg"] = e.angle_error_before_deg;
  j["angle_error_after_deg"] = e.angle_error_after_deg;
  j["gain"] = e.gain;
  return j;
}

Json ThermalFitToJson(const ThermalFitResult& fit, const ThermalFitOptions& options) {
  Json j = ThermalEvaluationToJson(fit.evaluation);
  j["status"] = FitStatusName(fit.status);
  j["message"] = fit.message;
  Json terms = Json::object(), sigma = Json::object();
  for (int k = 0; k < kTerms; ++k) {
    if (!fit.kept[k]) continue;
    terms[ThermalDriftModel::TermName(k)] = fit.model.k_dph[k];
    sigma[ThermalDriftModel::TermName(k)] = fit.sigma_dph[k];
  }
  j["terms"] = terms;
  j["sigma"] = sigma;
  Json tested = Json::array();
  for (const auto& t : fit.tested) {
    tested.push_back({{"term", t.name},
                      {"kept", t.kept},
                      {"estimate_dph", t.estimate_dph},
                      {"sigma_dph", t.sigma_dph},
                      {"full_model_estimate_dph", t.full_estimate_dph},
                      {"full_model_sigma_dph", t.full_sigma_dph},
                      {"full_model_t", t.full_t},
                      {"delta_bic_if_toggled", t.delta_bic_toggle}});
  }
  j["tested"] = tested;
  Json cands = Json::array();
  for (const auto& c : fit.candidates) {
    Json cj = {{"terms", c.terms}, {"bic", c.bic}};
    cj["cv_rms_dph"] = c.cv_rms_dph >= 0 ? Json(c.cv_rms_dph) : Json(nullptr);
    cands.push_back(cj);
  }
  j["candidates"] = cands;
  j["validation_agrees"] = fit.validation_agrees;
  j["selection"] = {{"criterion", "BIC over all 1024 subsets, GLS-prewhitened, effective sample size"},
                    {"n_bins", fit.n_bins},
                    {"n_eff", fit.n_eff},
                    {"bin_s", options.bin_s},
                    {"noise_white_dph", fit.noise_white_dph},
                    {"noise_wander_dph", fit.noise_wander_dph},
                    {"noise_wander_tau_s", fit.noise_wander_tau_s},
                    {"whitened_lag1_autocorrelation", fit.whitened_r1},
                    {"variance_inflation", fit.variance_inflation}};
  j["model"] = {{"t0_c", fit.model.t0_c},
                {"t1_c", fit.model.t1_c},
                {"g0_c_per_min", fit.model.g0_c_per_min},
                {"rate_window_s", options.rate.window_s},
                {"rate_order", options.rate.order},
                {"bin_s", options.bin_s}};
  return j;
}

ThermalModelFile ThermalModelFromJson(const Json& j, const std::string& file) {
  ThermalModelFile m;
  // The file `fog thermal --json` writes: every key it writes is allowed; the model is in 'terms' and 'model'.
  CheckKeys(j,
            {"terms", "model", "sigma", "status", "message", "tested", "candidates", "validation_agrees", "selection",
             "drift_before_dph", "drift_after_dph", "angle_error_before_deg", "angle_error_after_deg", "gain",
             "holdout", "comment"},
            file);
  if (!j.contains("terms") || !j.at("terms").is_object()) throw InputError(file, "missing object 'terms'");
  const Json& terms = j.at("terms");
  for (auto it = terms.begin(); it != terms.end(); ++it) {
    int found = -1;
    for (int k = 0; k < kTerms; ++k) {
      if (ThermalDriftModel::TermName(k) == it.key()) found = k;
    }
    if (found < 0) {
      std::vector<std::string> names;
      for (int k = 0; k < kTerms; ++k) names.push_back(ThermalDriftModel::TermName(k));
      CheckKeys(Json{{it.key(), 0}}, names, file + ": terms");
    }
    m.model.k_dph[found] = JsonNumber(terms, it.key(), file);
  }
  if (j.contains("model")) {
    const Json& mj = j.at("model");
    CheckKeys(mj, {"t0_c", "t1_c", "g0_c_per_min", "rate_window_s", "rate_order", "bin_s"}, file + ": model");
    m.model.t0_c = JsonNumberOr(mj, "t0_c", m.model.t0_c, file);
    m.model.t1_c = JsonNumberOr(mj, "t1_c", m.model.t1_c, file);
    m.model.g0_c_per_min = JsonNumberOr(mj, "g0_c_per_min", m.model.g0_c_per_min, file);
    m.rate.window_s = JsonNumberOr(mj, "rate_window_s", m.rate.window_s, file);
    m.rate.order = static_cast<int>(JsonIntOr(mj, "rate_order", m.rate.order, 1, 5, file + ": model"));
    m.bin_s = JsonNumberOr(mj, "bin_s", m.bin_s, file);
  }
  if (!(m.model.t1_c != m.model.t0_c) || !(m.model.g0_c_per_min != 0)) {
    throw InputError(file, "model normalisation (t0_c, t1_c, g0_c_per_min) is degenerate");
  }
  return m;
}

}  // namespace ssiu
