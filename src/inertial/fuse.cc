#include "inertial/fuse.h"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>

#include "core/attitude.h"
#include "core/csv.h"
#include "core/error.h"
#include "inertial/propagate.h"

namespace ssiu {
namespace {

constexpr double kDphToRadS = kDegToRad / 3600.0;
constexpr double kRadSToDph = 1.0 / kDphToRadS;

}  // namespace

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

StarTrackerLog ReadStarTrackerLog(const std::string& path) {
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
        throw InputError(path, "row " + std::to_string(r + 1) + ": sigma_cross_arcsec and sigma_roll_arcsec must be > 0");
      }
    }
  }
  return log;
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
}

Json FuseResult::ToJson() const {
  Json faults_json = Json::array();
  for (const auto& f : faults) faults_json.push_back(f.ToJson());
  return {{"status", status},
          {"message", message},
          {"bias_dph", {bias_dph.x(), bias_dph.y(), bias_dph.z()}},
          {"bias_sigma_dph", {bias_sigma_dph.x(), bias_sigma_dph.y(), bias_sigma_dph.z()}},
          {"faults", faults_json},
          {"gyros_in_use", gyros_in_use},
          {"n_gyro_samples", n_gyro_samples},
          {"n_st_used", n_st_used},
          {"n_st_rejected", n_st_rejected},
          {"longest_st_gap_s", longest_st_gap_s},
          {"st_residual_rms_arcsec", st_residual_rms_arcsec},
          {"seconds_elapsed", seconds_elapsed}};
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
    // Body rates: an orthogonal triad with the first gyro's noise figures.
    const auto& g0 = unit_in.gyros.front();
    unit = OrthogonalTriad(g0.arw_deg_per_sqrt_h, g0.bias_instability_dph);
    for (auto& g : unit.gyros) g = g0;
  }
  unit.Check("unit");
  const int n = unit.size();
  if (static_cast<int>(gyro.rates_dph.front().size()) != n) {
    throw InputError(gyro.file, "has " + std::to_string(gyro.rates_dph.front().size()) +
                                    " gyro columns but the unit has " + std::to_string(n) + " gyros");
  }
  if (st.t_s.empty() || st.t_s.front() >= gyro.t_s.back()) {
    res.status = "no_star_data";
    res.message = "no star-tracker sample within the gyro log";
    return res;
  }

  const GyroAxes axes = unit.Axes();
  const GyroVec arw = unit.NoiseArw();
  std::vector<bool> use(n, true);
  GyroVec correction = GyroVec::Zero(n);  // gyro-level parity bias removed after an isolation (deg/h)
  RateSolver solver(axes, arw, use);
  MekfNoise noise = FuseNoiseModel(unit, solver, options.bias_drift_floor_dph_per_sqrt_h);

  std::vector<double> dts;
  for (size_t k = 1; k < gyro.t_s.size(); ++k) dts.push_back(gyro.t_s[k] - gyro.t_s[k - 1]);
  std::nth_element(dts.begin(), dts.begin() + dts.size() / 2, dts.end());
  const double dt_nominal = dts[dts.size() / 2];
  const GyroVec sample_sigma_dph = arw * (60.0 / std::sqrt(dt_nominal));  // deg/sqrt(h) -> deg/h per sample

  const bool fdi_on = options.fdi && !gyro.body_rates && n >= 4;
  ParityMonitor monitor;
  if (fdi_on) monitor = ParityMonitor(axes, use, sample_sigma_dph, dt_nominal, options.fdi_options);
  StarRateIsolator isolator;
  bool isolating = false;
  std::deque<std::pair<double, Vec3>> bias_history;  // (t, bias rad/s), one per star update

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
    res.status = "no_star_data";
    res.message = "no star-tracker sample within the gyro log";
    return res;
  }
  Mekf filter;
  Mat6 p0 = Mat6::Zero();
  p0.block<3, 3>(0, 0) = st_r(j);
  const double b0 = options.init_bias_sigma_dph * kDphToRadS;
  p0.block<3, 3>(3, 3) = Mat3::Identity() * b0 * b0;
  filter.Init(st.q_inertial_from_body[j], Vec3::Zero(), p0);
  double t_cur = st.t_s[j];
  double resid_sum2 = 0;
  long resid_n = 0;
  double t_last_st = t_cur;
  ++j;
  res.n_st_used = 1;

  auto isolate = [&](int gi, double t, const std::string& method, const GyroVec& resid, double fault_dph) {
    FaultEvent& ev = res.faults.back();
    ev.gyro = gi + 1;
    ev.t_isolate_s = t;
    ev.status = "isolated";
    ev.method = method;
    ev.fault_dph = fault_dph;
    ev.residual_dph.assign(resid.data(), resid.data() + resid.size());
    correction = GyroVec::Zero(n);
    if (monitor.active() && monitor.ready()) correction = monitor.V().transpose() * monitor.baseline();
    // Between onset and isolation the filter took the fault's share of the rate solution for bias;
    // the new solution no longer carries it, so the estimate drops it and the covariance opens by
    // the same amount (the fault's size is only estimated).
    const Vec3 leak_rad_s = solver.Pinv().col(gi) * fault_dph * kDphToRadS;
    const double leak = leak_rad_s.norm();
    filter.ShiftBias(-leak_rad_s);
    use[gi] = false;
    solver = RateSolver(axes, arw, use);
    noise = FuseNoiseModel(unit, solver, options.bias_drift_floor_dph_per_sqrt_h);
    monitor = ParityMonitor(axes, use, sample_sigma_dph, dt_nominal, options.fdi_options);
    filter.InflateBias(leak);
    isolating = false;
  };

  int consecutive_rejects = 0;
  auto star_update = [&](size_t jj) {
    const double gap = st.t_s[jj] - t_last_st;
    res.longest_st_gap_s = std::max(res.longest_st_gap_s, gap);
    t_last_st = st.t_s[jj];
    // Star rates for isolation do not depend on the filter: every star sample counts.
    if (isolating) {
      if (gap > 5.0) isolator.BreakChain();
      isolator.AddStar(st.t_s[jj], st.q_inertial_from_body[jj]);
    }
    // A run of rejections means the filter, not the star tracker, is wrong: accept the next one.
    const double gate = consecutive_rejects >= 5 ? std::numeric_limits<double>::infinity() : options.nis_gate;
    const MekfUpdate u = filter.UpdateAttitude(st.q_inertial_from_body[jj], st_r(jj), gate);
    if (!u.accepted) {
      ++res.n_st_rejected;
      ++consecutive_rejects;
    } else {
      consecutive_rejects = 0;
      ++res.n_st_used;
      resid_sum2 += u.residual_rad.squaredNorm();
      ++resid_n;
      bias_history.emplace_back(st.t_s[jj], filter.bias());
      while (bias_history.size() > 2 && bias_history.front().first < st.t_s[jj] - 3 * options.fdi_options.window_s) {
        bias_history.pop_front();
      }
    }
    if (!isolating) return;
    FaultEvent& ev = res.faults.back();
    if (isolator.covered_s() >= options.fdi_options.isolation_window_s) {
      const GyroVec r = isolator.ResidualDph();
      const int gi = IsolateFromResiduals(r, use, options.fdi_options);
      if (gi >= 0) {
        isolate(gi, st.t_s[jj], "star_rates", r, r[gi]);
      } else if (st.t_s[jj] - ev.t_detect_s > options.fdi_options.isolation_timeout_s) {
        ev.status = "unresolved";
        ev.residual_dph.assign(r.data(), r.data() + r.size());
        isolating = false;
      }
    }
  };

  for (size_t k = 0; k < gyro.t_s.size(); ++k) {
    const double t_k = gyro.t_s[k];
    const double t_prev = k == 0 ? t_k - dt_nominal : gyro.t_s[k - 1];
    if (t_k <= t_cur) continue;
    const double full = t_k - t_prev;
    const GyroVec& g = gyro.rates_dph[k];
    const Vec3 w = solver.Solve(g - correction) * kDphToRadS;
    ++res.n_gyro_samples;

    if (fdi_on && !isolating && monitor.Feed(t_k, g)) {
      FaultEvent ev;
      ev.t_detect_s = t_k;
      ev.parity_jump_dph = monitor.jump().norm();
      ev.status = "detected";
      res.faults.push_back(ev);
      // The size of the step, not the window mean that crossed the threshold.
      const GyroVec step = monitor.StepEstimate(nullptr);
      const double worst_dph = LargestImpliedRateDph(monitor.V(), solver, use, step.norm());
      // The fault began at most one parity window ago and has turned the attitude since, unknown to
      // the filter: open the attitude covariance by that angle, or the NIS gate refuses the very
      // star fixes that would correct it.
      filter.InflateAttitude(worst_dph * kDphToRadS * options.fdi_options.window_s);
      const int gi = IsolateFromParity(monitor.V(), monitor.jump(), use, options.fdi_options);
      if (gi >= 0) {
        const double f = step.dot(monitor.V().col(gi)) / monitor.V().col(gi).squaredNorm();
        isolate(gi, t_k, "parity", GyroVec::Zero(n), f);
      } else {
        // Gyro-level biases before the fault: body bias from before the window plus the parity part.
        const Vec3 b_before = bias_history.empty() ? filter.bias() : bias_history.front().second;
        const GyroVec c = axes * (b_before * kRadSToDph) + monitor.V().transpose() * monitor.baseline();
        isolator = StarRateIsolator(axes, use, c);
        isolating = true;
        // Until isolation the fault feeds the bias: open its covariance by the largest body bias the
        // parity jump can imply, so that the filter follows instead of diverging.
        filter.InflateBias(worst_dph * kDphToRadS);
      }
    }

    while (j < st.t_s.size() && st.t_s[j] <= t_k) {
      if (st.t_s[j] <= t_cur) {  // a star sample at the very start time
        ++j;
        continue;
      }
      const double d = st.t_s[j] - t_cur;
      filter.Propagate(w, d, noise, std::abs(d - full) < 1e-9 * full);
      if (isolating) isolator.AddGyro(g, d);
      t_cur = st.t_s[j];
      star_update(j);
      ++j;
    }
    if (t_k > t_cur) {
      const double d = t_k - t_cur;
      filter.Propagate(w, d, noise, std::abs(d - full) < 1e-9 * full);
      if (isolating) isolator.AddGyro(g, d);
      t_cur = t_k;
    }
    if (static_cast<long>(k) % options.output_every == 0 || k + 1 == gyro.t_s.size()) {
      FusedSample s;
      s.t_s = t_k;
      s.q_inertial_from_body = filter.q();
      const Mat6& p = filter.P();
      for (int a = 0; a < 3; ++a) {
        s.sigma_rad[a] = std::sqrt(p(MekfIndex::kAttitude + a, MekfIndex::kAttitude + a));
        s.bias_sigma_dph[a] = std::sqrt(p(MekfIndex::kBias + a, MekfIndex::kBias + a)) * kRadSToDph;
      }
      s.bias_dph = filter.bias() * kRadSToDph;
      res.samples.push_back(s);
    }
  }
  res.status = "fused";
  res.bias_dph = filter.bias() * kRadSToDph;
  for (int a = 0; a < 3; ++a) {
    res.bias_sigma_dph[a] = std::sqrt(filter.P()(MekfIndex::kBias + a, MekfIndex::kBias + a)) * kRadSToDph;
  }
  for (int i = 0; i < n; ++i) {
    if (use[i]) res.gyros_in_use.push_back(i + 1);
  }
  res.st_residual_rms_arcsec = resid_n > 0 ? std::sqrt(resid_sum2 / (3.0 * resid_n)) * kRadToArcsec : 0.0;
  res.longest_st_gap_s = std::max(res.longest_st_gap_s, gyro.t_s.back() - t_last_st);
  res.message = std::to_string(res.n_st_used) + " star samples used, " + std::to_string(res.n_st_rejected) +
                " rejected, " + std::to_string(res.faults.size()) + " fault(s)";
  res.seconds_elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return res;
}

void WriteFusedAttitude(const std::string& path, const FuseResult& result) {
  std::vector<std::vector<double>> c(11);
  for (const auto& s : result.samples) {
    const auto q = ToWxyz(s.q_inertial_from_body);
    c[0].push_back(s.t_s);
    for (int a = 0; a < 4; ++a) c[1 + a].push_back(q[a]);
    for (int a = 0; a < 3; ++a) c[5 + a].push_back(s.sigma_rad[a] * kRadToArcsec);
    for (int a = 0; a < 3; ++a) c[8 + a].push_back(s.bias_dph[a]);
  }
  WriteCsv(path,
           {"t_s", "qw", "qx", "qy", "qz", "sigma_x_arcsec", "sigma_y_arcsec", "sigma_z_arcsec", "bx_dph", "by_dph",
            "bz_dph"},
           c, 15);
}

}  // namespace ssiu
