#include "inertial/fuse.h"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>

#include "ccsds/adm.h"
#include "core/attitude.h"
#include "core/csv.h"
#include "core/error.h"
#include "inertial/online_fusion.h"
#include "inertial/propagate.h"

namespace ssiu {

GyroLog ReadGyroLog(const std::string& path, int n_gyros) {
  const CsvTable t = ReadCsv(path);
  GyroLog log;
  log.file = path;
  log.t_s = t.Column("t_s");
  if (t.rows() < 2) throw InputError(path, "too few rows (need at least 2 gyro samples)");
  t.CheckIncreasing("t_s");
  std::vector<std::string> names;
  if (t.Has("wx_dph")) {
    log.body_rates = true;
    names = {"wx_dph", "wy_dph", "wz_dph"};
  } else {
    int n = n_gyros;
    if (n == 0) {
      while (t.Has("g" + std::to_string(n + 1) + "_dph")) ++n;
      if (n == 0) throw InputError(path, "missing columns: need wx_dph,wy_dph,wz_dph or g1_dph..gN_dph");
    }
    for (int i = 1; i <= n; ++i) names.push_back("g" + std::to_string(i) + "_dph");
  }
  if (names.size() > static_cast<size_t>(kMaxGyros)) throw InputError(path, "more than 6 gyro columns");
  std::vector<const std::vector<double>*> cols;
  for (const auto& n : names) cols.push_back(&t.Column(n));
  log.rates_dph.resize(t.rows());
  for (size_t r = 0; r < t.rows(); ++r) {
    GyroVec g(static_cast<int>(cols.size()));
    for (size_t c = 0; c < cols.size(); ++c) g[c] = (*cols[c])[r];
    log.rates_dph[r] = g;
  }
  return log;
}

namespace {

StarTrackerLog StarTrackerLogFromAdm(const AttitudeHistory& h) {
  StarTrackerLog log;
  log.file = h.file;
  log.epoch_utc = h.epoch_utc;
  for (const AdmState& s : h.states) {
    log.t_s.push_back(s.t_s);
    log.q_inertial_from_body.push_back(s.q_inertial_from_body);
  }
  // Sigmas only when the covariance covers every attitude epoch.
  if (h.covariances.size() == h.states.size()) {
    for (size_t k = 0; k < h.states.size(); ++k) {
      const std::vector<double>& d = h.covariances[k].diagonal;
      if (std::abs(h.covariances[k].t_s - h.states[k].t_s) > 1e-6 || !(d[0] + d[1] > 0) || !(d[2] > 0)) {
        log.sigma_cross_arcsec.clear();
        log.sigma_roll_arcsec.clear();
        break;
      }
      log.sigma_cross_arcsec.push_back(std::sqrt((d[0] + d[1]) / 2) * kRadToArcsec);
      log.sigma_roll_arcsec.push_back(std::sqrt(d[2]) * kRadToArcsec);
    }
  }
  return log;
}

}  // namespace

StarTrackerLog ReadStarTrackerLog(const std::string& path, const std::string& epoch_utc) {
  if (LooksLikeAdm(path)) {
    const AttitudeHistory h = ReadAdmFile(path, epoch_utc);
    if (h.states.size() < 1) throw InputError(path, "no attitude");
    return StarTrackerLogFromAdm(h);
  }
  const CsvTable t = ReadCsv(path);
  StarTrackerLog log;
  log.file = path;
  log.t_s = t.Column("t_s");
  t.CheckIncreasing("t_s");
  const auto &qw = t.Column("qw"), &qx = t.Column("qx"), &qy = t.Column("qy"), &qz = t.Column("qz");
  for (size_t r = 0; r < t.rows(); ++r) {
    const std::string what = path + ": row " + std::to_string(r + 1) + " quaternion";
    log.q_inertial_from_body.push_back(FromWxyz(qw[r], qx[r], qy[r], qz[r], what.c_str()));
  }
  if (t.Has("sigma_cross_arcsec") || t.Has("sigma_roll_arcsec")) {
    log.sigma_cross_arcsec = t.Column("sigma_cross_arcsec");
    log.sigma_roll_arcsec = t.Column("sigma_roll_arcsec");
    for (size_t r = 0; r < t.rows(); ++r) {
      if (!(log.sigma_cross_arcsec[r] > 0) || !(log.sigma_roll_arcsec[r] > 0)) {
        throw InputError(path,
                         "row " + std::to_string(r + 1) + ": sigma_cross_arcsec and sigma_roll_arcsec must be > 0");
      }
    }
  }
  return log;
}

void FusionPolicy::Check() const {
  auto pos = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v)) {
      throw InputError("fuse options", "policy." + std::string(name) + " must be a finite number > 0");
    }
  };
  if (accept_after_rejections < 1) throw InputError("fuse options", "policy.accept_after_rejections must be >= 1");
  pos(isolation_chain_gap_s, "isolation_chain_gap_s");
  pos(failed_after_s, "failed_after_s");
  if (!(settle_after_isolation_s >= 0) || !std::isfinite(settle_after_isolation_s)) {
    throw InputError("fuse options", "policy.settle_after_isolation_s must be a finite number >= 0");
  }
  pos(bias_history_s, "bias_history_s");
  pos(max_gyro_output_dph, "max_gyro_output_dph");
  pos(max_gyro_gap_s, "max_gyro_gap_s");
  auto count = [](int v, const char* name, int most) {
    if (v < 1 || v > most) {
      throw InputError("fuse options", "policy." + std::string(name) + " must be in [1, " + std::to_string(most) + "]");
    }
  };
  count(max_fault_events, "max_fault_events", 1 << 16);
  count(resync_after_samples, "resync_after_samples", 1 << 20);
  count(bias_history_max, "bias_history_max", 1 << 20);
  count(max_star_samples_kept, "max_star_samples_kept", 1 << 20);
}

void FuseOptions::Check() const {
  auto pos = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v)) throw InputError("fuse options", std::string(name) + " must be positive");
  };
  pos(st_sigma_cross_arcsec, "st_sigma_cross_arcsec");
  pos(st_sigma_roll_arcsec, "st_sigma_roll_arcsec");
  pos(init_bias_sigma_dph, "init_bias_sigma_dph");
  pos(nis_gate, "nis_gate");
  if (!(bias_drift_floor_dph_per_sqrt_h >= 0)) {
    throw InputError("fuse options", "bias_drift_floor_dph_per_sqrt_h must be >= 0");
  }
  if (output_every < 1) throw InputError("fuse options", "output_every must be >= 1");
  fdi_options.Check();
  policy.Check();
  calibration.Check();
}

const char* FusionStatusName(FusionStatus s) {
  switch (s) {
    case FusionStatus::kOk:
      return "ok";
    case FusionStatus::kDegraded:
      return "degraded";
    case FusionStatus::kFailed:
      return "failed";
  }
  return "failed";
}

const char* FuseStatusName(FuseStatus s) {
  switch (s) {
    case FuseStatus::kFused:
      return "fused";
    case FuseStatus::kDegraded:
      return "degraded";
    case FuseStatus::kFailed:
      return "failed";
    case FuseStatus::kNoStarData:
      return "no_star_data";
  }
  return "no_star_data";
}

Json FuseResult::ToJson() const {
  Json faults_json = Json::array();
  for (const auto& f : faults) faults_json.push_back(f.ToJson());
  return {{"status", FuseStatusName(status)},
          {"message", message},
          {"bias_dph", {bias_dph.x(), bias_dph.y(), bias_dph.z()}},
          {"bias_sigma_dph", {bias_sigma_dph.x(), bias_sigma_dph.y(), bias_sigma_dph.z()}},
          {"faults", faults_json},
          {"gyros_in_use", gyros_in_use},
          {"status_s", status_s},
          {"n_gyro_samples", n_gyro_samples},
          {"n_st_used", n_st_used},
          {"n_st_rejected", n_st_rejected},
          {"longest_st_gap_s", longest_st_gap_s},
          {"st_residual_rms_arcsec", st_residual_rms_arcsec},
          {"seconds_elapsed", seconds_elapsed},
          {"noise", noise}};
}

std::vector<GyroErrorModel> ReadAllanNoise(const std::string& path) {
  const Json j = ReadJsonFile(path);
  if (!j.is_object() && !(j.is_array() && !j.empty())) {
    throw InputError(path, "not an `ssiu allan --json` report (an object, or an array of them)");
  }
  const Json reports = j.is_array() ? j : Json::array({j});
  // Every key `ssiu allan --json` writes (calibration/allan_io.cc AllanReportJson and its provenance
  // in cli/allan.cc): anything else is a misspelling or another file, refused like every JSON input.
  static const std::vector<std::string> kReportKeys = {
      "file",    "column",    "channel",    "source",     "rate_unit", "tau_column", "sample_rate_hz",
      "n",       "adev_unit", "confidence", "edf_source", "tau_s",     "adev",       "adev_lo",
      "adev_hi", "edf",       "noise",      "model_adev", "fit",       "terms"};
  static const std::vector<std::string> kTermNames = {"quantization_arcsec",  "arw_deg_per_sqrt_h",
                                                      "bias_instability_dph", "rrw_deg_per_h_per_sqrt_h",
                                                      "rate_ramp_deg_per_h2", "bias_instability_floor_dph"};
  static const std::vector<std::string> kTermKeys = {
      "value", "sigma", "unit", "tau_range_s", "significant", "max_variance_fraction", "upper_bound"};
  std::vector<GyroErrorModel> out;
  for (size_t r = 0; r < reports.size(); ++r) {
    const std::string at = j.is_array() ? "[" + std::to_string(r) + "]." : "";
    const Json& rep = reports[r];
    if (!rep.is_object() || !rep.contains("terms") || !rep.at("terms").is_object()) {
      throw InputError(path, "missing object '" + at + "terms' (give `ssiu allan --json` output)");
    }
    CheckKeys(rep, kReportKeys, path + (at.empty() ? "" : ": " + at.substr(0, at.size() - 1)));
    CheckKeys(rep.at("terms"), kTermNames, path + ": " + at + "terms");
    for (auto it = rep.at("terms").begin(); it != rep.at("terms").end(); ++it) {
      if (it.value().is_object()) CheckKeys(it.value(), kTermKeys, path + ": " + at + "terms." + it.key());
    }
    // A term's value when the fit found it significant, else 0 (not distinguishable from none).
    auto term = [&](const char* key) {
      const Json& t = rep.at("terms");
      const std::string name = at + "terms." + key;
      if (!t.contains(key) || !t.at(key).is_object()) throw InputError(path, "missing object '" + name + "'");
      const Json& v = t.at(key);
      if (!v.contains("significant") || !v.at("significant").is_boolean()) {
        throw InputError(path, "field '" + name + ".significant' is missing or not true/false");
      }
      const double value = JsonNumber(v, "value", path + ": " + name);
      if (value < 0) throw InputError(path, "field '" + name + ".value' must be >= 0");
      return v.at("significant").get<bool>() ? value : 0.0;
    };
    GyroErrorModel g;
    g.arw_deg_per_sqrt_h = term("arw_deg_per_sqrt_h");
    g.bias_instability_dph = term("bias_instability_dph");
    g.rrw_dph_per_sqrt_h = term("rrw_deg_per_h_per_sqrt_h");
    if (!(g.arw_deg_per_sqrt_h > 0)) {
      throw InputError(path, "'" + at +
                                 "terms.arw_deg_per_sqrt_h' is not significant: no white rate noise for the "
                                 "filter (give --arw-deg-per-sqrt-h)");
    }
    out.push_back(g);
  }
  return out;
}

// The filter's noise model for the gyros in use: white rate noise and bias walk of the
// least-squares body rate (Markley & Crassidis eq. 6.93 spectral densities, in rad).
MekfNoise FuseNoiseModel(const GyroUnit& unit, const RateSolver& solver, double floor_dph_per_sqrt_h) {
  MekfNoise n;
  const double arw_to_rad = kDegToRad / 60.0;  // deg/sqrt(h) -> rad/sqrt(s)
  n.rate_white = solver.Cov() * (arw_to_rad * arw_to_rad);
  GyroParity d = GyroParity::Zero(unit.size(), unit.size());
  for (int i = 0; i < unit.size(); ++i) {
    const double s = unit.gyros[i].BiasDriftDphPerSqrtS() * kDphToRadS;
    d(i, i) = s * s;
  }
  n.bias_walk = solver.Pinv() * d * solver.Pinv().transpose();
  const double f = floor_dph_per_sqrt_h / 60.0 * kDphToRadS;
  n.bias_walk += Mat3::Identity() * (f * f + 1e-30);
  return n;
}

FuseResult Fuse(const GyroLog& gyro, const StarTrackerLog& st, const GyroUnit& unit_in, const FuseOptions& options) {
  const auto t_start = std::chrono::steady_clock::now();
  options.Check();
  FuseResult res;
  if (gyro.t_s.size() < 2) throw InputError(gyro.file, "too few rows (need at least 2 gyro samples)");
  GyroUnit unit = unit_in;
  if (gyro.body_rates) {
    // Body rates: an orthogonal triad; a 3-gyro unit gives the noise of x, y, z, any other its first gyro's.
    unit = OrthogonalTriad();
    for (int a = 0; a < 3; ++a) unit.gyros[a] = unit_in.gyros.at(unit_in.size() == 3 ? a : 0);
  }
  unit.Check("unit");
  {
    Json per_gyro = Json::array();
    for (const auto& g : unit.gyros) {
      per_gyro.push_back({{"arw_deg_per_sqrt_h", g.arw_deg_per_sqrt_h},
                          {"bias_instability_dph", g.bias_instability_dph},
                          {"rrw_dph_per_sqrt_h", g.rrw_dph_per_sqrt_h},
                          {"bias_walk_dph_per_sqrt_h", g.BiasDriftDphPerSqrtS() * 60.0}});
    }
    res.noise = per_gyro[0];
    res.noise["bias_instability_tau_s"] = unit.gyros[0].bias_instability_tau_s;
    res.noise["init_bias_sigma_dph"] = options.init_bias_sigma_dph;
    res.noise["bias_drift_floor_dph_per_sqrt_h"] = options.bias_drift_floor_dph_per_sqrt_h;
    res.noise["per_gyro"] = per_gyro;
  }
  const int n = unit.size();
  if (static_cast<int>(gyro.rates_dph.front().size()) != n) {
    throw InputError(gyro.file, "has " + std::to_string(gyro.rates_dph.front().size()) +
                                    " gyro columns but the unit has " + std::to_string(n) + " gyros");
  }
  if (st.t_s.empty() || st.t_s.front() >= gyro.t_s.back()) {
    res.status = FuseStatus::kNoStarData;
    res.message = "no star-tracker sample within the gyro log";
    return res;
  }

  std::vector<double> dts;
  for (size_t k = 1; k < gyro.t_s.size(); ++k) dts.push_back(gyro.t_s[k] - gyro.t_s[k - 1]);
  std::nth_element(dts.begin(), dts.begin() + dts.size() / 2, dts.end());
  const double dt_nominal = dts[dts.size() / 2];
  unit.rate_hz = 1.0 / dt_nominal;  // the log's own rate sets the per-sample noise
  FuseOptions fo = options;
  fo.fdi = options.fdi && !gyro.body_rates;
  // The on-board estimator, fed in time order (online_fusion.h): one implementation of the MEKF, the
  // fault detection and isolation and the status for `fuse` and `run`.
  OnlineFusion fusion(unit, fo);

  auto st_r = [&](size_t j) {
    const double c =
        (st.sigma_cross_arcsec.empty() ? options.st_sigma_cross_arcsec : st.sigma_cross_arcsec[j]) * kArcsecToRad;
    const double r =
        (st.sigma_roll_arcsec.empty() ? options.st_sigma_roll_arcsec : st.sigma_roll_arcsec[j]) * kArcsecToRad;
    return Mat3(Vec3(c * c, c * c, r * r).asDiagonal());
  };

  // Start at the first star sample at or after the start of the gyro log's first interval.
  size_t j = 0;
  const double log_start = gyro.t_s.front() - dt_nominal;
  while (j < st.t_s.size() && st.t_s[j] < log_start - 1e-9) ++j;
  if (j >= st.t_s.size()) {
    res.status = FuseStatus::kNoStarData;
    res.message = "no star-tracker sample within the gyro log";
    return res;
  }
  double resid_sum2 = 0, t_last_st = st.t_s[j];
  long resid_n = 0;
  const double t_start_fix = st.t_s[j];
  auto star_update = [&](size_t jj) {
    res.longest_st_gap_s = std::max(res.longest_st_gap_s, st.t_s[jj] - t_last_st);
    t_last_st = st.t_s[jj];
    const bool first = !fusion.initialised();
    const MekfUpdate u = fusion.AddAttitude(st.t_s[jj], st.q_inertial_from_body[jj], st_r(jj));
    if (u.accepted && !first) {
      resid_sum2 += u.residual_rad.squaredNorm();
      ++resid_n;
    }
  };
  FusionStatus worst = FusionStatus::kOk;
  double t_prev_out = t_start_fix;
  for (size_t k = 0; k < gyro.t_s.size(); ++k) {
    const double t_k = gyro.t_s[k];
    while (j < st.t_s.size() && st.t_s[j] < t_k - 1e-9) star_update(j++);
    fusion.AddGyro(t_k, gyro.rates_dph[k]);
    while (j < st.t_s.size() && st.t_s[j] <= t_k + 1e-9) star_update(j++);
    if (!fusion.initialised() || t_k <= t_start_fix) continue;
    const FusionStatus status = fusion.Status();
    worst = std::max(worst, status);
    res.status_s[FusionStatusName(status)] += t_k - t_prev_out;
    t_prev_out = t_k;
    if (static_cast<long>(k) % options.output_every == 0 || k + 1 == gyro.t_s.size()) {
      FusedSample s;
      s.t_s = t_k;
      s.q_inertial_from_body = fusion.q();
      s.sigma_rad = fusion.attitude_sigma_rad();
      s.bias_sigma_dph = fusion.bias_sigma_dph();
      s.bias_dph = fusion.bias_rad_s() * kRadSToDph;
      s.w_body_rad_s = fusion.last_rate_rad_s() - fusion.bias_rad_s();
      s.status = status;
      res.samples.push_back(s);
    }
  }
  while (j < st.t_s.size() && st.t_s[j] <= gyro.t_s.back() + 1e-9) star_update(j++);
  res.n_gyro_samples = fusion.n_gyro_samples();
  res.n_st_used = fusion.n_updates();
  res.n_st_rejected = fusion.n_rejected();
  res.faults = fusion.faults();
  res.gyros_in_use = fusion.GyrosInUse();
  res.status = worst == FusionStatus::kOk         ? FuseStatus::kFused
               : worst == FusionStatus::kDegraded ? FuseStatus::kDegraded
                                                  : FuseStatus::kFailed;
  res.bias_dph = fusion.bias_rad_s() * kRadSToDph;
  res.bias_sigma_dph = fusion.bias_sigma_dph();
  res.st_residual_rms_arcsec = resid_n > 0 ? std::sqrt(resid_sum2 / (3.0 * resid_n)) * kRadToArcsec : 0.0;
  res.longest_st_gap_s = std::max(res.longest_st_gap_s, gyro.t_s.back() - t_last_st);
  res.message = std::to_string(res.n_st_used) + " star samples used, " + std::to_string(res.n_st_rejected) +
                " rejected, " + std::to_string(res.faults.size()) + " fault(s)";
  res.seconds_elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return res;
}

void WriteFusedAttitude(const std::string& path, const FuseResult& result) {
  std::vector<std::vector<double>> c(12);
  for (const auto& s : result.samples) {
    const auto q = ToWxyz(s.q_inertial_from_body);
    c[0].push_back(s.t_s);
    for (int a = 0; a < 4; ++a) c[1 + a].push_back(q[a]);
    for (int a = 0; a < 3; ++a) c[5 + a].push_back(s.sigma_rad[a] * kRadToArcsec);
    for (int a = 0; a < 3; ++a) c[8 + a].push_back(s.bias_dph[a]);
    c[11].push_back(static_cast<int>(s.status));
  }
  WriteCsv(path,
           {"t_s", "qw", "qx", "qy", "qz", "sigma_x_arcsec", "sigma_y_arcsec", "sigma_z_arcsec", "bx_dph", "by_dph",
            "bz_dph", "status_code"},
           c, 15);
}

GyroUnit FuseUnitForLog(const GyroLog& log, const std::string& log_name, const std::string& unit_path,
                        const FuseNoiseGiven& noise, std::string* noise_source) {
  if (log.rates_dph.empty()) throw InputError(log_name, "has no samples");
  const int n_log = static_cast<int>(log.rates_dph.front().size());
  GyroUnit unit;
  std::string source = unit_path.empty() ? "default_unit" : "unit_file";
  if (!unit_path.empty()) {
    unit = LoadGyroUnit(unit_path);
    // Every g*_dph column is compared: reading only the unit's first N ignored a log's extra gyros
    // (a 3-gyro unit on a four-FOG log dropped g4 without a word).
    if (!log.body_rates && n_log != unit.size())
      throw InputError(log_name, "has g1_dph..g" + std::to_string(n_log) + "_dph columns for " + std::to_string(n_log) +
                                     " gyros but " + unit_path + " describes " + std::to_string(unit.size()));
  } else {
    unit = DefaultFourFogUnit();
    if (!log.body_rates && n_log != unit.size())
      throw InputError(log_name, "has g1_dph..gN_dph columns for " + std::to_string(n_log) +
                                     " gyros: give their unit.json (--unit)");
    if (log.body_rates && noise.any()) unit = OrthogonalTriad();  // body rates with their own noise: an ideal triad
  }
  const int n = log.body_rates ? (unit.size() == 3 ? 3 : 1) : unit.size();
  if (!noise.noise_file.empty()) {
    const std::vector<GyroErrorModel> m = ReadAllanNoise(noise.noise_file);
    if (m.size() != 1 && static_cast<int>(m.size()) != n)
      throw InputError(noise.noise_file,
                       "has " + std::to_string(m.size()) + " reports: give one, or one per " +
                           (log.body_rates ? std::string("body axis (3)") : "gyro (" + std::to_string(n) + ")"));
    for (int i = 0; i < unit.size(); ++i) {
      GyroErrorModel& g = unit.gyros[i];
      const GyroErrorModel& r = m[m.size() == 1 ? 0 : std::min<size_t>(i, m.size() - 1)];
      g.arw_deg_per_sqrt_h = r.arw_deg_per_sqrt_h;
      g.bias_instability_dph = r.bias_instability_dph;
      g.rrw_dph_per_sqrt_h = r.rrw_dph_per_sqrt_h;
    }
    source = "noise_file";
  }
  auto given = [&](const std::optional<double>& figure, bool positive, const char* name,
                   double GyroErrorModel::*field) {
    if (!figure) return;
    const double v = *figure;
    if (!std::isfinite(v) || v < 0 || (positive && v == 0))
      throw InputError(name, positive ? "must be a finite number > 0" : "must be a finite number >= 0");
    for (auto& g : unit.gyros) g.*field = v;
    source = "flags";
  };
  given(noise.arw_deg_per_sqrt_h, true, "arw_deg_per_sqrt_h", &GyroErrorModel::arw_deg_per_sqrt_h);
  given(noise.bias_instability_dph, false, "bias_instability_dph", &GyroErrorModel::bias_instability_dph);
  given(noise.rrw_dph_per_sqrt_h, false, "rrw_dph_per_sqrt_h", &GyroErrorModel::rrw_dph_per_sqrt_h);
  if (noise.init_bias_sigma_given) source = "flags";
  if (noise_source) *noise_source = source;
  return unit;
}

}  // namespace ssiu
