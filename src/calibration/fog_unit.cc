#include "calibration/fog_unit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "core/csv.h"
#include "core/error.h"
#include "core/stats.h"

namespace ssiu {
namespace {

// Regressor columns of one gyro's model; the first four are always in it.
enum Col { kWx, kWy, kWz, kBias, kAsym, kNonlin, kTemp, kTempRate, kNumCols };
constexpr int kNumBase = 4;
constexpr int kNumOptional = kNumCols - kNumBase;
const char* const kColName[kNumCols] = {"m_x",
                                        "m_y",
                                        "m_z",
                                        "bias",
                                        "scale_factor_asymmetry",
                                        "scale_factor_nonlinearity",
                                        "temperature",
                                        "temperature_rate"};
const char* const kColUnit[kNumCols] = {
    "1", "1", "1", "deg/h", "ppm", "ppm per deg/s", "deg/h per C", "deg/h per C/min"};

// Bin means of one step's samples: the data of the GLS fit.
struct Bin {
  int log = 0;
  double t_s = 0;      // centre
  double t_key_s = 0;  // on the common timeline of the bias wander
  int count = 0;
  Vec3 ref = Vec3::Zero();
  std::vector<double> g, abs_n, sq_n;  // per gyro: mean output, mean |n.w|, mean (n.w)|n.w|
  double temp_c = 0, rate_c_per_min = 0;
};

// The two normals of a nominal axis (GyroUnit::SensingAxis's convention).
void Normals(const Vec3& n, Vec3* u, Vec3* v) {
  Eigen::Index m;
  n.cwiseAbs().minCoeff(&m);
  *u = n.cross(Vec3::Unit(m)).normalized();
  *v = n.cross(*u);
}

struct Fit {
  std::vector<int> cols;
  Eigen::VectorXd beta;
  Eigen::MatrixXd cov;  // scaled by max(1, chi2/dof)
  double rss = 0, bic = 0;
};

// Least squares on whitened data (columns `cols` of xw).
Fit FitColumns(const Eigen::MatrixXd& xw, const Eigen::VectorXd& yw, const std::vector<int>& cols) {
  const int n = static_cast<int>(yw.size()), k = static_cast<int>(cols.size());
  Eigen::MatrixXd x(n, k);
  for (int c = 0; c < k; ++c) x.col(c) = xw.col(cols[c]);
  Fit f;
  f.cols = cols;
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(x);
  f.beta = qr.solve(yw);
  f.rss = (yw - x * f.beta).squaredNorm();
  const double scale = std::max(1.0, f.rss / std::max(1, n - k));
  f.cov = (x.transpose() * x).inverse() * scale;
  // Gaussian BIC with the scale estimated (Schwarz 1978): n ln(RSS/n) + k ln n.
  f.bic = n * std::log(f.rss / n) + k * std::log(static_cast<double>(n));
  return f;
}

std::vector<int> SubsetColumns(int mask) {
  std::vector<int> cols = {kWx, kWy, kWz, kBias};
  for (int o = 0; o < kNumOptional; ++o) {
    if (mask & (1 << o)) cols.push_back(kNumBase + o);
  }
  return cols;
}

int Index(const std::vector<int>& cols, int c) {
  for (size_t k = 0; k < cols.size(); ++k) {
    if (cols[k] == c) return static_cast<int>(k);
  }
  return -1;
}

}  // namespace

void UnitCalibrationOptions::Check() const {
  if (!(bin_s > 0) || !std::isfinite(bin_s)) throw InputError("fog unit-calibrate", "--bin-s must be positive");
  if (!(settle_s >= 0) || !std::isfinite(settle_s)) throw InputError("fog unit-calibrate", "--settle-s must be >= 0");
  if (!(step_dph > 0)) throw InputError("fog unit-calibrate", "--step-dph must be positive");
  if (!std::isnan(temp_ref_c) && !(std::abs(temp_ref_c) < 1000))
    throw InputError("fog unit-calibrate", "--temp-ref-c must be a temperature in C");
  rate.Check();
}

UnitBenchLog ReadUnitBenchLog(const std::string& path, int n_gyros) {
  const CsvTable csv = ReadCsv(path);
  if (csv.rows() < 10) throw InputError(path, "fewer than 10 rows");
  UnitBenchLog log;
  log.file = path;
  log.t_s = csv.Column("t_s");
  csv.CheckIncreasing("t_s");
  for (int i = 1; i <= n_gyros; ++i) log.g_dph.push_back(csv.Column("g" + std::to_string(i) + "_dph"));
  const auto& rx = csv.Column("ref_x_dph");
  const auto& ry = csv.Column("ref_y_dph");
  const auto& rz = csv.Column("ref_z_dph");
  for (size_t k = 0; k < csv.rows(); ++k) log.ref_dph.emplace_back(rx[k], ry[k], rz[k]);
  if (csv.Has("temp_c")) log.temp_c = csv.Column("temp_c");
  return log;
}

UnitCalibrationResult CalibrateUnit(const std::vector<UnitBenchLog>& logs, const GyroUnit& nominal,
                                    const UnitCalibrationOptions& o) {
  o.Check();
  nominal.Check("nominal unit");
  if (logs.empty()) throw InputError("fog unit-calibrate", "no bench log given");
  const int n_g = nominal.size();
  UnitCalibrationResult res;
  res.n_logs = static_cast<int>(logs.size());
  res.have_temperature = true;
  for (const auto& log : logs) {
    if (static_cast<int>(log.g_dph.size()) != n_g)
      throw InputError(log.file, "needs g1_dph..g" + std::to_string(n_g) + "_dph for the unit's gyros");
    res.have_temperature &= !log.temp_c.empty();
  }

  // 1. Steps (maximal runs of a steady reference), settling dropped; bins of bin_s within a step.
  std::vector<Bin> bins;
  std::vector<std::vector<double>> diffs(n_g);  // first differences of g - n.ref, per gyro
  double t_offset = 0, last_end = -std::numeric_limits<double>::infinity();
  for (size_t li = 0; li < logs.size(); ++li) {
    const UnitBenchLog& log = logs[li];
    const size_t ns = log.t_s.size();
    std::vector<double> dts;
    for (size_t k = 1; k < ns; ++k) dts.push_back(log.t_s[k] - log.t_s[k - 1]);
    const double dt = Median(dts);
    const int per_bin = std::max(1, static_cast<int>(std::lround(o.bin_s / dt)));
    // Logs that follow one another in time share one timeline of the bias wander; a log whose clock
    // starts again is placed after the last (its wander is then correlated with the last's end: the
    // conservative choice for a campaign run in one sitting).
    if (!(log.t_s.front() > last_end)) t_offset = last_end - log.t_s.front() + dt;
    last_end = log.t_s.back() + t_offset;
    std::vector<size_t> kept;
    double t_step = -std::numeric_limits<double>::infinity();  // a log's start is not a table step
    Bin cur;
    auto close = [&](bool force_keep) {
      if (cur.count > 0 && (force_keep || 2 * cur.count >= per_bin)) {
        const double c = cur.count;
        cur.ref /= c;
        for (int i = 0; i < n_g; ++i) cur.g[i] /= c, cur.abs_n[i] /= c, cur.sq_n[i] /= c;
        cur.t_s /= c;
        cur.t_key_s = cur.t_s + t_offset;
        bins.push_back(cur);
      }
      cur = Bin{};
    };
    for (size_t k = 0; k < ns; ++k) {
      const bool gap = k > 0 && log.t_s[k] - log.t_s[k - 1] > 5 * dt;
      const bool step = k > 0 && (log.ref_dph[k] - log.ref_dph[k - 1]).cwiseAbs().maxCoeff() > o.step_dph;
      if (gap || step) {
        close(false);
        ++res.n_steps;
        t_step = log.t_s[k];
      }
      if (log.t_s[k] - t_step < o.settle_s) continue;
      if (cur.count == 0) {
        cur.log = static_cast<int>(li);
        cur.g.assign(n_g, 0), cur.abs_n.assign(n_g, 0), cur.sq_n.assign(n_g, 0);
      }
      const Vec3& w = log.ref_dph[k];
      cur.ref += w;
      cur.t_s += log.t_s[k];
      for (int i = 0; i < n_g; ++i) {
        const double wn = nominal.axes_body[i].dot(w);
        cur.g[i] += log.g_dph[i][k];
        cur.abs_n[i] += std::abs(wn);
        cur.sq_n[i] += wn * std::abs(wn);
        // Differences within a steady step: the slow parts of g - n.ref cancel, white noise stays.
        if (!kept.empty() && kept.back() + 1 == k && !step && !gap) {
          const size_t p = k - 1;
          diffs[i].push_back((log.g_dph[i][k] - nominal.axes_body[i].dot(log.ref_dph[k])) -
                             (log.g_dph[i][p] - nominal.axes_body[i].dot(log.ref_dph[p])));
        }
      }
      kept.push_back(k);
      ++res.n_samples_used;
      if (++cur.count >= per_bin) close(true);
    }
    close(false);
    ++res.n_steps;
    if (res.have_temperature) {
      std::vector<double> at;
      size_t first = bins.size();
      while (first > 0 && bins[first - 1].log == static_cast<int>(li)) --first;
      for (size_t b = first; b < bins.size(); ++b) at.push_back(bins[b].t_s);
      const TemperatureEstimate te = EstimateTemperatureRate(log.t_s, log.temp_c, at, o.rate);
      for (size_t b = first; b < bins.size(); ++b) {
        bins[b].temp_c = te.temp_c[b - first];
        bins[b].rate_c_per_min = te.rate_c_per_min[b - first];
      }
    }
  }
  const int nb = static_cast<int>(bins.size());
  res.n_bins = nb;
  if (nb < 4 * (kNumCols + 2)) {
    throw InputError("fog unit-calibrate", "only " + std::to_string(nb) + " bins of " + std::to_string(o.bin_s) +
                                               " s after settling: too short a campaign");
  }
  {
    Eigen::MatrixXd r(nb, 3);
    for (int b = 0; b < nb; ++b) {
      r.row(b) = bins[b].ref.transpose();
      res.max_rate_dps = std::max(res.max_rate_dps, bins[b].ref.norm() / 3600.0);
    }
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(r);
    res.reference_condition = svd.singularValues()(2) / svd.singularValues()(0);
    if (!(res.reference_condition > 1e-3)) {
      throw InputError("fog unit-calibrate",
                       "the reference rates do not span 3-D (rotations about three independent axes are needed to "
                       "fit the sensing axes)");
    }
  }
  if (res.have_temperature) {
    double sum = 0;
    for (const auto& b : bins) sum += b.temp_c;
    res.temp_ref_c = std::isnan(o.temp_ref_c) ? sum / nb : o.temp_ref_c;
  }

  res.unit = nominal;
  res.unit.calibrated = true;
  for (int i = 0; i < n_g; ++i) {
    GyroCalibration gc;
    const Vec3 n = nominal.axes_body[i];
    gc.nominal_axis = n;
    // 2. White noise of one sample from the first differences (robust: MAD), as ARW.
    std::vector<double>& d = diffs[i];
    const double med = Median(d);
    for (double& x : d) x = std::abs(x - med);
    const double dt = 1.0 / std::max(1e-9, nominal.rate_hz);
    gc.white_dph = std::max(1e-12, 1.4826 * Median(d) / std::sqrt(2.0));
    {
      // The samples' own interval, not the unit's nominal rate: bins hold `count` samples.
      std::vector<double> dts;
      for (size_t k = 1; k < logs[0].t_s.size(); ++k) dts.push_back(logs[0].t_s[k] - logs[0].t_s[k - 1]);
      const double dt_log = dts.empty() ? dt : Median(dts);
      gc.arw_deg_per_sqrt_h = gc.white_dph * std::sqrt(dt_log) / 60.0;  // sigma = ARW * 60 / sqrt(dt)
    }
    // 3. Noise covariance of the bin means: white / count, plus the nominal unit's bias wander
    // (Gauss-Markov components, exp(-|dt|/tau); rate random walk, q^2 min(t, t')), within a timeline.
    const GyroErrorModel& em = nominal.gyros[i];
    Eigen::MatrixXd sigma = Eigen::MatrixXd::Zero(nb, nb);
    const double s_gm = o.wander_from_unit ? em.GaussMarkovSigmaDph() : 0.0;
    const double q_rrw = o.wander_from_unit ? em.rrw_dph_per_sqrt_h / 60.0 : 0.0;  // (deg/h)/sqrt(s)
    const double t0 = bins.front().t_key_s;
    for (int a = 0; a < nb; ++a) {
      sigma(a, a) = gc.white_dph * gc.white_dph / bins[a].count;
      for (int b = 0; b <= a; ++b) {
        const double dtab = std::abs(bins[a].t_key_s - bins[b].t_key_s);
        double c = 0;
        for (double tau : em.bias_instability_tau_s) c += s_gm * s_gm * std::exp(-dtab / tau);
        c += q_rrw * q_rrw * (std::min(bins[a].t_key_s, bins[b].t_key_s) - t0);
        sigma(a, b) += c;
        if (a != b) sigma(b, a) += c;
      }
    }
    const Eigen::LLT<Eigen::MatrixXd> llt(sigma);
    if (llt.info() != Eigen::Success) throw std::runtime_error("fog unit-calibrate: noise covariance not positive");
    // 4. Regressors (deg/h), whitened.
    Eigen::MatrixXd x = Eigen::MatrixXd::Zero(nb, kNumCols);
    Eigen::VectorXd y(nb);
    for (int b = 0; b < nb; ++b) {
      const Bin& bn = bins[b];
      x(b, kWx) = bn.ref.x(), x(b, kWy) = bn.ref.y(), x(b, kWz) = bn.ref.z();
      x(b, kBias) = 1;
      x(b, kAsym) = 1e-6 * bn.abs_n[i];
      x(b, kNonlin) = 1e-6 * bn.sq_n[i] / 3600.0;
      if (res.have_temperature) x(b, kTemp) = bn.temp_c - res.temp_ref_c, x(b, kTempRate) = bn.rate_c_per_min;
      y[b] = bn.g[i];
    }
    const Eigen::MatrixXd xw = llt.matrixL().solve(x);
    const Eigen::VectorXd yw = llt.matrixL().solve(y);
    // 5. All subsets of the optional terms by BIC (temperature terms only with temp_c logged).
    std::vector<Fit> fits;
    const int n_opt = res.have_temperature ? kNumOptional : 2;
    for (int mask = 0; mask < (1 << n_opt); ++mask) fits.push_back(FitColumns(xw, yw, SubsetColumns(mask)));
    std::vector<int> order(fits.size());
    for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
    std::sort(order.begin(), order.end(), [&](int a, int b) { return fits[a].bic < fits[b].bic; });
    const Fit& best = fits[order[0]];
    const Fit& full = fits.back();
    const int best_mask = order[0];
    for (int k : order) {
      UnitCandidate c;
      for (int oi = 0; oi < n_opt; ++oi) {
        if (k & (1 << oi)) c.terms.push_back(kColName[kNumBase + oi]);
      }
      c.bic = fits[k].bic;
      gc.candidates.push_back(c);
    }
    const int nk = static_cast<int>(best.cols.size());
    gc.chi2_per_dof = best.rss / std::max(1, nb - nk);
    {
      Eigen::VectorXd beta_full = Eigen::VectorXd::Zero(kNumCols);
      for (int k = 0; k < nk; ++k) beta_full[best.cols[k]] = best.beta[k];
      gc.rms_residual_dph = std::sqrt((y - x * beta_full).squaredNorm() / nb);
    }
    for (int c = 0; c < kNumBase + n_opt; ++c) {
      UnitTermStat t;
      t.name = kColName[c], t.unit = kColUnit[c];
      t.optional = c >= kNumBase;
      const int kb = Index(best.cols, c), kf = Index(full.cols, c);
      t.kept = kb >= 0;
      if (t.kept) {
        t.estimate = best.beta[kb], t.sigma = std::sqrt(best.cov(kb, kb));
        t.t = t.estimate / t.sigma;
        t.p_value = std::erfc(std::abs(t.t) / std::sqrt(2.0));
      }
      t.full_estimate = full.beta[kf], t.full_sigma = std::sqrt(full.cov(kf, kf));
      t.full_t = t.full_estimate / t.full_sigma;
      if (t.optional) t.delta_bic_toggle = fits[best_mask ^ (1 << (c - kNumBase))].bic - best.bic;
      gc.terms.push_back(t);
    }
    auto kept_value = [&](int c) { return Index(best.cols, c) >= 0 ? best.beta[Index(best.cols, c)] : 0.0; };
    gc.scale_factor_asymmetry_ppm = kept_value(kAsym);
    gc.scale_factor_nonlinearity_ppm_per_dps = kept_value(kNonlin);
    gc.temp_dph_per_c = kept_value(kTemp);
    gc.temp_rate_dph_per_c_per_min = kept_value(kTempRate);
    // 6. Derived parameters and their covariance (first-order propagation, J P J').
    const Vec3 m(best.beta[0], best.beta[1], best.beta[2]);
    const double mn = m.norm();
    Vec3 u, v;
    Normals(n, &u, &v);
    gc.axis = m / mn;
    gc.bias_dph = best.beta[3];
    gc.scale_factor_ppm = 1e6 * (mn - 1);
    // The tilts as GyroUnit::SensingAxis defines them: a ~ n + mu u + mv v, so mu = (m.u)/(m.n).
    const double mdn = m.dot(n);
    gc.misalignment_arcsec[0] = m.dot(u) / mdn * kRadToArcsec;
    gc.misalignment_arcsec[1] = m.dot(v) / mdn * kRadToArcsec;
    gc.axis_change_arcsec = std::atan2(gc.axis.cross(n).norm(), gc.axis.dot(n)) * kRadToArcsec;
    Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(4, nk);
    jac(0, 3) = 1;
    jac.block<1, 3>(1, 0) = 1e6 * (m / mn).transpose();
    jac.block<1, 3>(2, 0) = kRadToArcsec * (u / mdn - m.dot(u) / (mdn * mdn) * n).transpose();
    jac.block<1, 3>(3, 0) = kRadToArcsec * (v / mdn - m.dot(v) / (mdn * mdn) * n).transpose();
    gc.cov = jac * best.cov * jac.transpose();

    GyroErrorModel& out = res.unit.gyros[i];
    res.unit.axes_body[i] = gc.axis;
    out.misalignment_arcsec[0] = out.misalignment_arcsec[1] = 0;  // the fitted axis is the sensing direction
    out.bias_dph = gc.bias_dph;
    out.scale_factor_ppm = gc.scale_factor_ppm;
    out.scale_factor_asymmetry_ppm = gc.scale_factor_asymmetry_ppm;
    out.scale_factor_nonlinearity_ppm_per_dps = gc.scale_factor_nonlinearity_ppm_per_dps;
    res.gyros.push_back(gc);
  }
  res.unit.Check("calibrated unit");
  return res;
}

Json UnitCalibrationToJson(const UnitCalibrationResult& r, const UnitCalibrationOptions& o) {
  Json gyros = Json::array();
  for (size_t i = 0; i < r.gyros.size(); ++i) {
    const GyroCalibration& g = r.gyros[i];
    auto sd = [&](int k) { return std::sqrt(g.cov(k, k)); };
    Json terms = Json::array();
    for (const auto& t : g.terms) {
      Json jt = {{"name", t.name},
                 {"unit", t.unit},
                 {"optional", t.optional},
                 {"kept", t.kept},
                 {"estimate", t.estimate},
                 {"sigma", t.sigma},
                 {"t", t.t},
                 {"p_value", t.p_value},
                 {"full_estimate", t.full_estimate},
                 {"full_sigma", t.full_sigma},
                 {"full_t", t.full_t}};
      if (t.optional) jt["delta_bic_toggle"] = t.delta_bic_toggle;
      terms.push_back(jt);
    }
    Json cands = Json::array();
    for (const auto& c : g.candidates) cands.push_back({{"terms", c.terms}, {"bic", c.bic}});
    Json cov = Json::array();
    for (int a = 0; a < 4; ++a) cov.push_back({g.cov(a, 0), g.cov(a, 1), g.cov(a, 2), g.cov(a, 3)});
    Json jg = {{"gyro", i + 1},
               {"nominal_axis", {g.nominal_axis.x(), g.nominal_axis.y(), g.nominal_axis.z()}},
               {"axis", {g.axis.x(), g.axis.y(), g.axis.z()}},
               {"axis_change_arcsec", g.axis_change_arcsec},
               {"bias_dph", g.bias_dph},
               {"bias_sigma_dph", sd(0)},
               {"scale_factor_ppm", g.scale_factor_ppm},
               {"scale_factor_sigma_ppm", sd(1)},
               {"misalignment_arcsec", {g.misalignment_arcsec[0], g.misalignment_arcsec[1]}},
               {"misalignment_sigma_arcsec", {sd(2), sd(3)}},
               {"scale_factor_asymmetry_ppm", g.scale_factor_asymmetry_ppm},
               {"scale_factor_nonlinearity_ppm_per_dps", g.scale_factor_nonlinearity_ppm_per_dps},
               {"covariance_order", {"bias_dph", "scale_factor_ppm", "misalignment_u_arcsec", "misalignment_v_arcsec"}},
               {"covariance", cov},
               {"terms", terms},
               {"candidates", cands},
               {"white_noise_dph", g.white_dph},
               {"arw_deg_per_sqrt_h", g.arw_deg_per_sqrt_h},
               {"chi2_per_dof", g.chi2_per_dof},
               {"rms_residual_dph", g.rms_residual_dph}};
    if (r.have_temperature) {
      jg["temp_dph_per_c"] = g.temp_dph_per_c;
      jg["temp_rate_dph_per_c_per_min"] = g.temp_rate_dph_per_c_per_min;
    }
    gyros.push_back(jg);
  }
  Json j = {{"status", FitStatusName(r.status)},
            {"message", r.message},
            {"gyros", gyros},
            {"n_logs", r.n_logs},
            {"n_steps", r.n_steps},
            {"n_bins", r.n_bins},
            {"n_samples_used", r.n_samples_used},
            {"max_rate_dps", r.max_rate_dps},
            {"reference_condition", r.reference_condition},
            {"have_temperature", r.have_temperature},
            {"options",
             {{"bin_s", o.bin_s},
              {"settle_s", o.settle_s},
              {"step_dph", o.step_dph},
              {"rate_window_s", o.rate.window_s},
              {"wander_from_unit", o.wander_from_unit}}},
            {"unit", GyroUnitToJson(r.unit)}};
  if (r.have_temperature) j["temp_ref_c"] = r.temp_ref_c;
  return j;
}

}  // namespace ssiu
