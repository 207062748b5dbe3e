// The bench logs of `ssiu discover gyro`: reading and checking them, their bins (with the spectral line
// test on the raw samples, which sees what the bins average away), and the design built from them (the
// stacked bins and the candidate regressor columns).
#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <limits>
#include <map>
#include <string>
#include <unsupported/Eigen/FFT>
#include <vector>

#include "core/csv.h"
#include "core/error.h"
#include "core/types.h"
#include "discover/discover_gyro_internal.h"
#include "discover/discover_gyro_lag.h"

namespace ssiu::discover_internal {

constexpr double kArcsecPerRad = 206264.80624709636;

namespace {

// The largest n' <= n whose only prime factors are 2, 3 and 5 (a fast FFT length).
size_t SmoothLength(size_t n) {
  for (size_t m = n; m > 1; --m) {
    size_t r = m;
    for (size_t f : {2, 3, 5}) {
      while (r % f == 0) r /= f;
    }
    if (r == 1) return m;
  }
  return n;
}

// Binning keeps what is slower than the bins and averages away the rest: a vibration pickup or an
// electrical tone at 0.5-50 Hz on a 100 Hz rate-table log leaves no trace in the bin means. This test
// looks at the band the bins discard. The raw drift y = w - ref minus its bin mean (so nothing of the
// bins' band is left), with the within-bin parts of ref, |ref| and d(ref)/dt regressed out (the fitted
// causes' content at high rate: scale factor, asymmetry, time delay on the rate steps' edges); its
// periodogram I_k = |X_k|^2 / N above 0.5 / bin_s, each ordinate against the local noise level S (the
// median of its block of 2048 ordinates / ln 2, robust to the line itself and to a coloured noise
// floor). Under white (or smoothly coloured) noise g = I_k / S is Exp(1); the block median's sampling
// error (relative sd 1.44 / sqrt(B), the median of B exponentials) is taken in as a lognormal factor,
// P(g > x) = exp(-x + x^2 sd^2 / 2); Bonferroni over the M ordinates tested: p = M P(g_max > x).
// The amplitude of a sinusoid at an ordinate is 2 sqrt(I_k / N).
void SpectralLineTest(const GyroBenchLog& log, const std::vector<double>& dref, const std::vector<int>& bin_of, int nb,
                      LogBins* b) {
  const size_t n = log.t_s.size();
  const double dt = (log.t_s.back() - log.t_s.front()) / static_cast<double>(n - 1);
  if (!(b->bin_s >= 12 * dt) || n < 4096) return;
  for (size_t i = 1; i < n; ++i) {
    if (std::abs(log.t_s[i] - log.t_s[i - 1] - dt) > 0.05 * dt) return;  // not evenly sampled
  }
  // Row i: the drift and the three columns, each minus its bin mean (two passes; the 3x3 normal equations
  // keep memory at the FFT's own).
  constexpr int kCols = 3;
  auto row = [&](size_t i) {
    return Eigen::Vector4d(log.w_dph[i] - log.ref_dph[i], log.ref_dph[i], std::abs(log.ref_dph[i]), dref[i]);
  };
  std::vector<Eigen::Vector4d> mean(nb, Eigen::Vector4d::Zero());
  std::vector<double> cnt(nb, 0.0);
  for (size_t i = 0; i < n; ++i) mean[bin_of[i]] += row(i), cnt[bin_of[i]] += 1;
  for (int k = 0; k < nb; ++k) mean[k] /= std::max(cnt[k], 1.0);
  Eigen::Matrix3d zz = Eigen::Matrix3d::Zero();
  Eigen::Vector3d zy = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector4d v = row(i) - mean[bin_of[i]];
    zz += v.tail<kCols>() * v.tail<kCols>().transpose();
    zy += v.tail<kCols>() * v(0);
  }
  // Columns that do not move within the bins (a constant rate) are dropped by the pseudo-inverse.
  const Eigen::Vector3d beta = zz.completeOrthogonalDecomposition().pseudoInverse() * zy;
  const size_t nf = SmoothLength(n);
  std::vector<double> in(nf);
  for (size_t i = 0; i < nf; ++i) {
    const Eigen::Vector4d v = row(i) - mean[bin_of[i]];
    in[i] = v(0) - v.tail<kCols>().dot(beta.allFinite() ? beta : Eigen::Vector3d::Zero());
  }
  std::vector<std::complex<double>> spec;
  Eigen::FFT<double> fft;
  fft.fwd(spec, in);
  // From the bins' Nyquist frequency up (what the bins' own tests cannot see). Removing the bin means takes
  // a share of the noise's power there too: white noise keeps h(f) = 1 - D(f)^2 of it, D the bin mean's
  // response sin(pi f m dt) / (m sin(pi f dt)) for m samples per bin (h >= 0.59 from 0.5 / bin_s up), so
  // each ordinate is divided by h before it meets the local level.
  const size_t k_lo = static_cast<size_t>(std::ceil(0.5 / b->bin_s * nf * dt)), k_hi = (nf - 1) / 2;
  const double spb = b->bin_s / dt;
  auto kept = [&](size_t k) {
    const double x = kPi * static_cast<double>(k) / static_cast<double>(nf);
    const double dm = std::sin(spb * x) / (spb * std::sin(x));
    return std::max(0.5, 1 - dm * dm);
  };
  constexpr size_t kBlock = 2048;
  if (k_lo + kBlock > k_hi) return;
  const double sd = 1.44 / std::sqrt(static_cast<double>(kBlock));
  double best_log_p = 0, best_g = 0;
  size_t best_k = 0;
  const size_t m = k_hi - k_lo + 1;
  // Past g = 1 / sd^2 the lognormal factor would turn P back up: the bound there holds for all larger g.
  const double g_cap = 1 / (sd * sd);
  for (size_t start = k_lo, end = 0; start <= k_hi; start = end) {
    // The last block is joined to the one before when it would be short.
    end = std::min(k_hi + 1, start + kBlock);
    if (k_hi + 1 - end < kBlock / 2) end = k_hi + 1;
    std::vector<double> power;
    for (size_t k = start; k < end; ++k) power.push_back(std::norm(spec[k]) / static_cast<double>(nf) / kept(k));
    std::vector<double> sorted = power;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double level = sorted[sorted.size() / 2] / std::log(2.0);
    for (size_t j = 0; j < power.size() && level > 0; ++j) {
      const double g = power[j] / level;
      const double ge = std::min(g, g_cap);
      if (g > best_g) best_g = g, best_log_p = -ge + 0.5 * ge * ge * sd * sd, best_k = start + j;
    }
  }
  b->line_tested = true;
  b->line_power_ratio = best_g;
  b->line_p = std::min(1.0, static_cast<double>(m) * std::exp(std::min(0.0, best_log_p)));
  b->line_frequency_hz = best_k / (nf * dt);
  b->line_amplitude_dph = 2 * std::sqrt(std::norm(spec[best_k]) / kept(best_k)) / static_cast<double>(nf);
}

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
  std::vector<int> bin_of(n);
  for (size_t i = 0; i < n; ++i) {
    const int k = std::min(nb - 1, static_cast<int>((log.t_s[i] - t0) / b.bin_s));
    bin_of[i] = k;
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
    if (!log.bn_ut.empty()) x[kBn] += log.bn_ut[i];
    if (!log.be_ut.empty()) x[kBe] += log.be_ut[i];
    if (!log.bh_ut.empty()) x[kBh] += log.bh_ut[i];
    x[kScale] += log.ref_dph[i] * 1e-6;
    x[kAbsRef] += std::abs(log.ref_dph[i]) * 1e-6;
    x[kDelay] += -dref[i];
  }
  // Bin means of every logged column other than t_s and w_dph, for the residual test.
  std::map<std::string, const std::vector<double>*> logged = {{"ref_dph", &log.ref_dph}, {"temp_c", &log.temp_c}};
  if (has_az) logged["azimuth_deg"] = &log.azimuth_deg;
  if (!log.bn_ut.empty()) logged["bn_ut"] = &log.bn_ut;
  if (!log.be_ut.empty()) logged["be_ut"] = &log.be_ut;
  if (!log.bh_ut.empty()) logged["bh_ut"] = &log.bh_ut;
  for (const auto& [name, v] : log.other) logged[name] = &v;
  std::map<std::string, std::vector<double>> col_sum;
  for (const auto& [name, v] : logged) {
    std::vector<double>& cs = col_sum[name];
    cs.assign(nb, 0.0);
    for (size_t i = 0; i < n; ++i) cs[bin_of[i]] += (*v)[i];
  }
  std::map<std::string, std::vector<double>> nl_sum;
  double ref_max = 0;
  for (double v : log.ref_dph) ref_max = std::max(ref_max, std::abs(v));
  if (has_az || ref_max > 0) {
    const std::vector<std::string> names = has_az ? std::vector<std::string>{"sin(2 azimuth)", "cos(2 azimuth)"}
                                                  : std::vector<std::string>{"ref^2", "|ref|", "ref^3"};
    for (const auto& name : names) nl_sum[name].assign(nb, 0.0);
    for (size_t i = 0; i < n; ++i) {
      const int k = bin_of[i];
      if (has_az) {
        const double p2 = 2 * log.azimuth_deg[i] * kDegToRad;
        nl_sum["sin(2 azimuth)"][k] += std::sin(p2);
        nl_sum["cos(2 azimuth)"][k] += std::cos(p2);
      } else {
        const double u = log.ref_dph[i] / ref_max;
        nl_sum["ref^2"][k] += u * u;
        nl_sum["|ref|"][k] += std::abs(u);
        nl_sum["ref^3"][k] += u * u * u;
      }
    }
  }
  std::vector<int> compact(nb, -1);
  for (int k = 0; k < nb; ++k) {
    if (cnt[k] == 0) continue;
    compact[k] = static_cast<int>(b.t_s.size());
    for (auto& [name, cs] : col_sum) b.column_mean[name].push_back(cs[k] / cnt[k]);
    for (auto& [name, cs] : nl_sum) b.nonlinear_mean[name].push_back(cs[k] / cnt[k]);
    b.t_s.push_back(sum_t[k] / cnt[k]);
    b.y_dph.push_back(sum_y[k] / cnt[k]);
    auto x = sum_x[k];
    for (double& v : x) v /= cnt[k];
    b.x.push_back(x);
  }
  for (int c = 0; c < 3; ++c) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const auto& x : b.x) lo = std::min(lo, x[kBn + c]), hi = std::max(hi, x[kBn + c]);
    b.field_span_ut[c] = b.x.empty() ? 0.0 : hi - lo;
  }
  // Temperature terms at the bin centres (local polynomial of fog_thermal.h).
  const TemperatureEstimate te = EstimateTemperatureRate(log.t_s, log.temp_c, b.t_s, o.rate);
  ThermalDriftModel m;
  if (!te.temp_c.empty()) {
    const auto [lo, hi] = std::minmax_element(te.temp_c.begin(), te.temp_c.end());
    b.temp_span_c = *hi - *lo;
  }
  for (size_t k = 0; k < b.t_s.size(); ++k) {
    const double z1 = m.Z1(te.temp_c[k]), z2 = m.Z2(te.rate_c_per_min[k]);
    b.x[k][kT1] = z1;
    b.x[k][kT2] = z1 * z1;
    b.x[k][kG1] = z2;
  }
  SpectralLineTest(log, dref, bin_of, nb, &b);
  b.sample_bin.resize(n);
  for (size_t i = 0; i < n; ++i) b.sample_bin[i] = compact[bin_of[i]];
  return b;
}

}  // namespace

// 1. The design: every log's bins stacked (offset per log), the regressor columns, the measured rate
// minus the reference, and one bias column per log.
Design BuildDesign(const std::vector<GyroBenchLog>& logs, const GyroDiscoverOptions& o) {
  Design d;
  for (const auto& log : logs) {
    CheckGyroBenchLog(log);
    d.offset.push_back(d.n);
    d.bins.push_back(MakeLogBins(log, o));
    d.n += static_cast<int>(d.bins.back().t_s.size());
  }
  const int l = static_cast<int>(logs.size());
  if (d.n < 40 + l) throw InputError(logs.front().file, "too few bins (" + std::to_string(d.n) + ") for discovery");
  // thermal_lag's time constant (1 min to 6 h, at most the longest log), when the temperature moves.
  double temp_span = 0, longest_s = 0;
  for (int r = 0; r < l; ++r) {
    temp_span = std::max(temp_span, d.bins[r].temp_span_c);
    longest_s = std::max(longest_s, logs[r].t_s.back() - logs[r].t_s.front());
  }
  d.lag_dtau = VectorXd::Zero(d.n);
  if (temp_span >= o.min_temp_span_c) {
    std::vector<LagLog> lag_logs;
    for (int r = 0; r < l; ++r) {
      lag_logs.push_back({&logs[r].t_s, &logs[r].temp_c, &d.bins[r].sample_bin, static_cast<int>(d.bins[r].t_s.size()),
                          &d.bins[r].y_dph});
    }
    const ThermalLagScan scan = ScanThermalLag(lag_logs, 60.0, std::min(6 * 3600.0, std::max(120.0, longest_s)));
    if (scan.ok) {
      d.lag_tau_s = scan.tau_s;
      d.lag_positions = scan.positions;
      for (int r = 0; r < l; ++r) {
        for (size_t k = 0; k < d.bins[r].t_s.size(); ++k) {
          d.bins[r].x[k][kLag] = scan.column[r][k];
          d.lag_dtau(d.offset[r] + static_cast<int>(k)) = scan.d_column_d_tau[r][k];
        }
      }
    }
  }
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
  return d;
}

// 2. Which columns the data can test; standardises the usable ones in d->cols (scale: their RMS) and
// returns the columns of the full model.
std::vector<int> UsableColumns(Design* design, const GyroDiscoverOptions& o, std::vector<bool>* usable_out,
                               std::vector<double>* scale_out) {
  Design& d = *design;
  const int l = static_cast<int>(d.bins.size());
  // Applicability: a column is usable when it is not (nearly) a per-log constant. Regressors are
  // standardised (scaled to unit RMS after removing per-log means) for conditioning.
  std::vector<bool>& usable = *usable_out;
  std::vector<double>& scale = *scale_out;
  usable.assign(kNumCols, false);
  scale.assign(kNumCols, 1.0);
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
  // Temperature terms need a temperature that moves (physical bounds, docs/discrepancy.md): fitted to
  // a log whose temperature hardly moves they explain anything with absurd coefficients.
  double temp_span = 0;
  for (const auto& b : d.bins) temp_span = std::max(temp_span, b.temp_span_c);
  if (temp_span < o.min_temp_span_c) usable[kT1] = usable[kT2] = usable[kG1] = usable[kLag] = false;
  // Likewise a logged field component must move: a magnetometer's noise alone gives absurd sensitivities.
  for (int c = 0; c < 3; ++c) {
    double span = 0;
    for (const auto& b : d.bins) span = std::max(span, b.field_span_ut[c]);
    if (span < o.min_field_span_ut) usable[kBn + c] = false;
  }
  // |ref| splits the scale factor by sign only when the rates take both signs: where they keep one
  // sign within each log it is the scale-factor column again.
  if (usable[kAbsRef] && usable[kScale]) {
    double sab = 0, saa = 0, sbb = 0;
    for (int r = 0; r < l; ++r) {
      const int m = static_cast<int>(d.bins[r].t_s.size());
      VectorXd a = d.cols.col(kAbsRef).segment(d.offset[r], m), b = d.cols.col(kScale).segment(d.offset[r], m);
      a.array() -= a.mean();
      b.array() -= b.mean();
      sab += a.dot(b), saa += a.squaredNorm(), sbb += b.squaredNorm();
    }
    if (std::abs(sab) > 0.995 * std::sqrt(saa * sbb)) usable[kAbsRef] = false;
  }
  std::vector<int> full_cols;
  for (int c = 0; c < kNumCols; ++c) {
    if (usable[c] && c != kMis && c != kLag) full_cols.push_back(c);  // misalignment is nested in the harmonic
  }
  if (!usable[kMagSin] && usable[kMis]) full_cols.push_back(kMis);
  return full_cols;
}

}  // namespace ssiu::discover_internal

namespace ssiu {

namespace {

void Fail(const std::string& what) { throw InputError("options", what); }

}  // namespace

void GyroDiscoverOptions::Check() const {
  if (!(alpha > 0 && alpha < 0.5)) Fail("alpha must be in (0, 0.5)");
  if (max_bins_per_log < 50) Fail("max_bins_per_log must be >= 50");
  if (max_noise_lag < 2) Fail("max_noise_lag must be >= 2");
  if (!(wander_tau_max_s > 0)) Fail("wander_tau_max_s must be > 0");
  if (cv_blocks < 6) Fail("cv_blocks must be >= 6");
  if (!(gain_alpha > 0 && gain_alpha < 0.5)) Fail("gain_alpha must be in (0, 0.5)");
  if (!std::isfinite(min_block_z)) Fail("min_block_z must be finite");
  if (!(min_temp_span_c >= 0)) Fail("min_temp_span_c must be >= 0");
  if (!(min_field_span_ut >= 0)) Fail("min_field_span_ut must be >= 0");
  if (!(rrw_min_log_s >= 0)) Fail("rrw_min_log_s must be >= 0");
  if (!(periodic_min_cycles >= 2)) Fail("periodic_min_cycles must be >= 2");
  if (!(residual_alpha > 0 && residual_alpha < 0.5)) Fail("residual_alpha must be in (0, 0.5)");
  if (residual_lags < 3) Fail("residual_lags must be >= 3");
  rate.Check();
}

void CheckGyroBenchLog(const GyroBenchLog& log) {
  const size_t n = log.t_s.size();
  if (n < 50) throw InputError(log.file, "too few rows (" + std::to_string(n) + ", need >= 50)");
  auto same = [&](const std::vector<double>& v, const char* name) {
    if (v.size() != n) throw InputError(log.file, std::string("column ") + name + " has a different length");
    for (size_t i = 0; i < n; ++i) {
      if (!std::isfinite(v[i])) {
        throw InputError(log.file,
                         std::string("column ") + name + " row " + std::to_string(i + 1) + ": not a finite number");
      }
    }
  };
  same(log.t_s, "t_s");
  same(log.w_dph, "w_dph");
  same(log.ref_dph, "ref_dph");
  same(log.temp_c, "temp_c");
  if (!log.azimuth_deg.empty()) same(log.azimuth_deg, "azimuth_deg");
  if (!log.bn_ut.empty()) same(log.bn_ut, "bn_ut");
  if (!log.be_ut.empty()) same(log.be_ut, "be_ut");
  if (!log.bh_ut.empty()) same(log.bh_ut, "bh_ut");
  for (const auto& [name, v] : log.other) same(v, name.c_str());
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
  if (t.Has("bn_ut")) log.bn_ut = t.Column("bn_ut");
  if (t.Has("be_ut")) log.be_ut = t.Column("be_ut");
  if (t.Has("bh_ut")) log.bh_ut = t.Column("bh_ut");
  // Other columns are kept when every cell is a number (conventions: never an error).
  for (const auto& name : t.header) {
    if (name == "t_s" || name == "w_dph" || name == "ref_dph" || name == "temp_c" || name == "azimuth_deg" ||
        name == "bn_ut" || name == "be_ut" || name == "bh_ut" || log.other.count(name)) {
      continue;
    }
    try {
      log.other[name] = t.Column(name);
    } catch (const InputError&) {
    }
  }
  CheckGyroBenchLog(log);
  return log;
}

}  // namespace ssiu
