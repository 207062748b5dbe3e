#include "discover/discover_gyro_lag.h"

#include <algorithm>
#include <cmath>

namespace ssiu {
namespace {

// The normalisation of eq. (1)'s Z1 (inertial/fog_error_model.h ThermalDriftModel defaults).
constexpr double kT0C = 20.0, kT1C = 30.0;

// Per-log demeaned cross products of the lag column x with the drift y and with itself.
void CrossProducts(const std::vector<double>& x, const std::vector<double>& y, double* sxy, double* sxx, double* syy) {
  const int m = static_cast<int>(x.size());
  if (m == 0) return;
  double mx = 0, my = 0;
  for (int k = 0; k < m; ++k) mx += x[k], my += y[k];
  mx /= m, my /= m;
  for (int k = 0; k < m; ++k) {
    *sxy += (x[k] - mx) * (y[k] - my);
    *sxx += (x[k] - mx) * (x[k] - mx);
    *syy += (y[k] - my) * (y[k] - my);
  }
}

// Correlation of two columns after removing each log's mean.
double Correlation(const std::vector<std::vector<double>>& a, const std::vector<std::vector<double>>& b) {
  double sab = 0, saa = 0, sbb = 0;
  for (size_t r = 0; r < a.size(); ++r) CrossProducts(a[r], b[r], &sab, &saa, &sbb);
  return saa > 0 && sbb > 0 ? sab / std::sqrt(saa * sbb) : 1.0;
}

}  // namespace

std::vector<double> LaggedTemperatureBins(const LagLog& log, double tau_s) {
  const std::vector<double>& t = *log.t_s;
  const std::vector<double>& temp = *log.temp_c;
  const std::vector<int>& bin = *log.bin_of;
  std::vector<double> sum(log.n_bins, 0.0), cnt(log.n_bins, 0.0);
  double lag = temp.empty() ? kT0C : temp.front();
  for (size_t i = 0; i < t.size(); ++i) {
    if (i > 0) {
      // tau dT_lag/dt = T - T_lag over one sample interval with T at the interval's mean: exact to
      // second order in h / tau (h is seconds, tau minutes), and it averages the channel's noise.
      const double e = std::exp(-(t[i] - t[i - 1]) / tau_s);
      lag = lag * e + (1 - e) * 0.5 * (temp[i] + temp[i - 1]);
    }
    if (bin[i] < 0) continue;
    sum[bin[i]] += lag;
    cnt[bin[i]] += 1;
  }
  for (int k = 0; k < log.n_bins; ++k) sum[k] = cnt[k] > 0 ? (sum[k] / cnt[k] - kT0C) / (kT1C - kT0C) : 0.0;
  return sum;
}

ThermalLagScan ScanThermalLag(const std::vector<LagLog>& logs, double tau_min_s, double tau_max_s) {
  ThermalLagScan out;
  if (logs.empty() || !(tau_max_s > tau_min_s) || !(tau_min_s > 0)) return out;
  auto columns = [&](double tau) {
    std::vector<std::vector<double>> c;
    for (const auto& log : logs) c.push_back(LaggedTemperatureBins(log, tau));
    return c;
  };
  // Residual sum of squares of the drift on a bias per log and one K: Syy - Sxy^2 / Sxx.
  auto rss = [&](const std::vector<std::vector<double>>& c) {
    double sxy = 0, sxx = 0, syy = 0;
    for (size_t r = 0; r < logs.size(); ++r) CrossProducts(c[r], *logs[r].y_dph, &sxy, &sxx, &syy);
    return sxx > 0 ? syy - sxy * sxy / sxx : syy;
  };
  constexpr int kGrid = 48;
  const double step = std::log(tau_max_s / tau_min_s) / (kGrid - 1);
  std::vector<double> grid_rss(kGrid);
  std::vector<std::vector<std::vector<double>>> last_kept;  // the columns counted as independent positions
  int best = 0;
  for (int g = 0; g < kGrid; ++g) {
    const auto c = columns(tau_min_s * std::exp(g * step));
    grid_rss[g] = rss(c);
    if (grid_rss[g] < grid_rss[best]) best = g;
    // Independent positions: a new one whenever the column has turned away from the last counted one
    // (correlation below 0.9), the counterpart of periodic_drift's independent frequencies.
    if (last_kept.empty() || std::abs(Correlation(last_kept.back(), c)) < 0.9) last_kept.push_back(c);
  }
  out.positions = static_cast<int>(last_kept.size());
  // Golden-section refinement of ln(tau) between the best grid point's neighbours.
  double lo = std::log(tau_min_s) + std::max(0, best - 1) * step;
  double hi = std::log(tau_min_s) + std::min(kGrid - 1, best + 1) * step;
  const double r = 0.5 * (std::sqrt(5.0) - 1);
  double a = hi - r * (hi - lo), b = lo + r * (hi - lo);
  double fa = rss(columns(std::exp(a))), fb = rss(columns(std::exp(b)));
  for (int it = 0; it < 30; ++it) {
    if (fa < fb) {
      hi = b, b = a, fb = fa, a = hi - r * (hi - lo), fa = rss(columns(std::exp(a)));
    } else {
      lo = a, a = b, fa = fb, b = lo + r * (hi - lo), fb = rss(columns(std::exp(b)));
    }
  }
  const double ln_tau = std::min(fa, fb) < grid_rss[best] ? (fa < fb ? a : b) : std::log(tau_min_s) + best * step;
  out.tau_s = std::exp(ln_tau);
  out.column = columns(out.tau_s);
  const double h = 0.01 * out.tau_s;
  const auto up = columns(out.tau_s + h), down = columns(out.tau_s - h);
  for (size_t k = 0; k < logs.size(); ++k) {
    std::vector<double> dc(up[k].size());
    for (size_t i = 0; i < dc.size(); ++i) dc[i] = (up[k][i] - down[k][i]) / (2 * h);
    out.d_column_d_tau.push_back(dc);
  }
  out.ok = true;
  return out;
}

}  // namespace ssiu
