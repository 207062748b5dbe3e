#include "sim/gyro_sim.h"

#include <Eigen/Dense>
#include <cmath>
#include <filesystem>

#include "core/attitude.h"
#include "core/csv.h"
#include "core/error.h"
#include "core/rng.h"
#include "inertial/propagate.h"

namespace ssiu {
namespace {

std::vector<double> Numbers(const Json& j, const std::string& key, size_t n, const std::string& file) {
  const Json& a = j.at(key);
  if (!a.is_array() || (n > 0 && a.size() != n)) {
    throw InputError(file, "field '" + key + "' must be an array of " + std::to_string(n) + " numbers");
  }
  std::vector<double> v;
  for (const auto& x : a) {
    if (!x.is_number() || !std::isfinite(x.get<double>())) {
      throw InputError(file, "field '" + key + "' must hold finite numbers");
    }
    v.push_back(x.get<double>());
  }
  return v;
}

Vec3 Vec3From(const Json& j, const std::string& key, const std::string& file) {
  const auto v = Numbers(j, key, 3, file);
  return Vec3(v[0], v[1], v[2]);
}

std::vector<std::array<double, 2>> Pairs(const Json& j, const std::string& key, const std::string& file) {
  std::vector<std::array<double, 2>> out;
  if (!j.at(key).is_array()) throw InputError(file, "field '" + key + "' must be an array of [a, b] pairs");
  for (const auto& p : j.at(key)) {
    if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number()) {
      throw InputError(file, "field '" + key + "' must be an array of [a, b] pairs");
    }
    out.push_back({p[0].get<double>(), p[1].get<double>()});
  }
  return out;
}

// Body (x at azimuth from north, z up) -> inertial at sidereal angle 0 for a site at latitude lat.
Quat StaticAttitude(double lat_rad, double az_rad) {
  const Vec3 up(std::cos(lat_rad), 0, std::sin(lat_rad));
  const Vec3 north(-std::sin(lat_rad), 0, std::cos(lat_rad));
  const Vec3 east(0, 1, 0);
  const Vec3 x = std::cos(az_rad) * north + std::sin(az_rad) * east;
  Mat3 c;
  c.col(0) = x;
  c.col(1) = up.cross(x);
  c.col(2) = up;
  return Quat(c).normalized();
}

// Integral of the body rate over [ta, tb] as two Simpson halves, and the rotation vector of the body
// over the interval with the two-sample coning term (Savage 1998, eq. 38 with sub-increments).
struct Increment {
  Vec3 integral, rotation;
};
Increment Integrate(const MotionProfile& p, double ta, double tb) {
  const double h = tb - ta;
  auto w = [&](double f) { return p.RateBodyRadS(ta + f * h); };
  const Vec3 w0 = w(0), w1 = w(0.25), w2 = w(0.5), w3 = w(0.75), w4 = w(1);
  const Vec3 a1 = (h / 12.0) * (w0 + 4 * w1 + w2);
  const Vec3 a2 = (h / 12.0) * (w2 + 4 * w3 + w4);
  return {a1 + a2, a1 + a2 + (2.0 / 3.0) * a1.cross(a2)};
}

}  // namespace

double TemperatureProgramme::TempC(double t) const {
  double temp = start_c, t0 = 0;
  for (const auto& s : segments) {
    const double d = std::min(std::max(t - t0, 0.0), s[0]);
    temp += s[1] / 60.0 * d;
    t0 += s[0];
    if (t < t0) break;
  }
  return temp;
}

double TemperatureProgramme::RateCPerMin(double t) const {
  double t0 = 0;
  for (const auto& s : segments) {
    if (t >= t0 && t < t0 + s[0]) return s[1];
    t0 += s[0];
  }
  return 0.0;
}

Vec3 MotionProfile::RateBodyRadS(double t) const {
  const double lat = latitude_deg * kDegToRad;
  if (type == "static" || type == "temperature") {
    const double az = azimuth_deg * kDegToRad;
    return kEarthRateRadS * Vec3(std::cos(lat) * std::cos(az), std::cos(lat) * std::sin(az), std::sin(lat));
  }
  if (type == "bench") {
    size_t k = 0;
    double t0 = 0;
    while (k + 1 < bench.size() && t >= t0 + bench[k].duration_s) t0 += bench[k++].duration_s;
    const BenchSegment& s = bench[k];
    // Table frame: z up, x at the table angle from north (local frame north, west, up). The Earth
    // rate in it, plus the table's own rate about up, then into the body by the mounting.
    const double theta = (s.table_deg + s.rate_dps * (t - t0)) * kDegToRad;
    const Vec3 earth_local = kEarthRateRadS * Vec3(std::cos(lat), 0, std::sin(lat));
    const Vec3 w_table =
        Eigen::AngleAxisd(-theta, Vec3::UnitZ()) * earth_local + s.rate_dps * kDegToRad * Vec3::UnitZ();
    const Quat table_from_body = Quat::FromTwoVectors(s.up_body.normalized(), Vec3::UnitZ());
    return table_from_body.conjugate() * w_table;
  }
  if (type == "slew") {
    if (t < slew_start_s || t >= slew_end_s) return Vec3::Zero();
    return axis_body.normalized() * (rate_dps * kDegToRad);
  }
  Vec3 w;  // sine
  for (int a = 0; a < 3; ++a) {
    const double per = periods_s[a] > 0 ? periods_s[a] : period_s;
    w[a] = amplitude_dps[a] * kDegToRad * std::sin(2 * kPi * t / per);
  }
  return w;
}

bool MotionProfile::InStarOutage(double t) const {
  for (const auto& o : st_outages_s) {
    if (t >= o[0] && t < o[1]) return true;
  }
  return false;
}

void MotionProfile::Check(const std::string& file, int n_gyros) const {
  if (type != "static" && type != "slew" && type != "sine" && type != "temperature" && type != "bench") {
    throw InputError(file, "type must be static, slew, sine, temperature or bench (got '" + type + "')");
  }
  if (type == "bench" && bench.empty()) throw InputError(file, "bench: a bench profile needs at least one segment");
  for (const auto& b : bench) {
    if (!(b.duration_s > 0) || !std::isfinite(b.duration_s))
      throw InputError(file, "bench: duration_s must be positive");
    if (!b.up_body.allFinite() || !(b.up_body.norm() > 0)) throw InputError(file, "bench: up must be a nonzero vector");
    if (!std::isfinite(b.table_deg) || !(std::abs(b.rate_dps) <= 1000)) {
      throw InputError(file, "bench: table_deg must be finite and |rate_dps| <= 1000");
    }
  }
  if (!(slew_start_s >= 0) || !(slew_end_s > slew_start_s)) {
    throw InputError(file, "slew: need 0 <= start_s < end_s");
  }
  if (!(std::abs(latitude_deg) <= 90)) throw InputError(file, "latitude_deg must be in [-90, 90]");
  if (type == "slew" && !(axis_body.norm() > 0)) throw InputError(file, "axis must be nonzero");
  if (!std::isfinite(rate_dps) || !amplitude_dps.allFinite()) throw InputError(file, "rates must be finite");
  if (!(period_s > 0)) throw InputError(file, "period_s must be positive");
  if (!(periods_s.minCoeff() >= 0) || !periods_s.allFinite()) throw InputError(file, "periods_s must be >= 0");
  // Above the gyro rates a star tracker is absurd, and 1e9 Hz ran for hours.
  if (!(st_rate_hz > 0 && st_rate_hz <= 1000)) throw InputError(file, "star_tracker.rate_hz must be in (0, 1000]");
  if (!(st_sigma_cross_arcsec >= 0) || !(st_sigma_roll_arcsec >= 0)) {
    throw InputError(file, "star tracker sigmas must be >= 0");
  }
  for (const auto& s : temperature.segments) {
    if (!(s[0] >= 0) || !std::isfinite(s[1])) {
      throw InputError(file, "temperature.segments need [duration_s >= 0, rate_c_per_min]");
    }
  }
  for (const auto& o : st_outages_s) {
    // [t0, t1) with t1 < t0 would silently mean no outage at all.
    if (!std::isfinite(o[0]) || !std::isfinite(o[1]) || !(o[1] >= o[0])) {
      throw InputError(file, "star_tracker.outages_s need [start_s, end_s] with finite start_s <= end_s");
    }
  }
  for (const auto& f : faults) {
    if (f.gyro < 1 || f.gyro > n_gyros) throw InputError(file, "faults: gyro must be 1.." + std::to_string(n_gyros));
    if (!std::isfinite(f.t_s) || !std::isfinite(f.step_dph) || !std::isfinite(f.ramp_dph_per_h)) {
      throw InputError(file, "faults: t_s, step_dph and ramp_dph_per_h must be finite");
    }
    if (!(f.noise_dph >= 0) || !std::isfinite(f.noise_dph)) throw InputError(file, "faults: noise_dph must be >= 0");
    if (!(f.end_s > f.t_s)) throw InputError(file, "faults: end_s must be after t_s");
  }
}

// One entry of `faults`: gyro and t_s required; step_dph, ramp_dph_per_h (or ramp_dph_per_s),
// noise_dph, stuck and end_s optional.
GyroFault GyroFaultFromJson(const Json& f, const std::string& file) {
  if (!f.is_object()) throw InputError(file, "faults: each fault must be an object");
  CheckKeys(f, {"gyro", "t_s", "step_dph", "ramp_dph_per_h", "ramp_dph_per_s", "noise_dph", "stuck", "end_s"},
            file + ": faults");
  GyroFault g;
  g.gyro = static_cast<int>(JsonInt(f, "gyro", 1, kMaxGyros, file + ": faults"));
  g.t_s = JsonNumber(f, "t_s", file);
  g.step_dph = JsonNumberOr(f, "step_dph", 0, file);
  g.ramp_dph_per_h = JsonNumberOr(f, "ramp_dph_per_h", 0, file);
  if (f.contains("ramp_dph_per_s")) {
    if (f.contains("ramp_dph_per_h")) throw InputError(file, "faults: give ramp_dph_per_h or ramp_dph_per_s, not both");
    g.ramp_dph_per_h = 3600.0 * JsonNumber(f, "ramp_dph_per_s", file);
  }
  g.noise_dph = JsonNumberOr(f, "noise_dph", 0, file);
  g.stuck = JsonBoolOr(f, "stuck", g.stuck, file + ": faults");
  if (f.contains("end_s")) g.end_s = JsonNumber(f, "end_s", file);
  return g;
}

Json GyroFault::ToJson() const {
  Json j = {{"gyro", gyro}, {"t_s", t_s}, {"step_dph", step_dph}, {"ramp_dph_per_h", ramp_dph_per_h}};
  if (noise_dph != 0) j["noise_dph"] = noise_dph;
  if (stuck) j["stuck"] = true;
  if (std::isfinite(end_s)) j["end_s"] = end_s;
  return j;
}

MotionProfile MotionProfileFromJson(const Json& j, const std::string& file) {
  if (!j.is_object()) throw InputError(file, "profile must be a JSON object");
  CheckKeys(
      j,
      {"type", "latitude_deg", "azimuth_deg", "rate_dps", "period_s", "axis", "amplitude_dps", "magnetic_field_ut",
       "q0", "temperature", "star_tracker", "faults", "comment", "start_s", "end_s", "bench", "periods_s"},
      file);
  MotionProfile p;
  if (j.contains("type")) {
    if (!j["type"].is_string()) throw InputError(file, "field 'type' must be a string");
    p.type = j["type"].get<std::string>();
  }
  p.latitude_deg = JsonNumberOr(j, "latitude_deg", p.latitude_deg, file);
  p.azimuth_deg = JsonNumberOr(j, "azimuth_deg", p.azimuth_deg, file);
  p.rate_dps = JsonNumberOr(j, "rate_dps", p.rate_dps, file);
  p.period_s = JsonNumberOr(j, "period_s", p.period_s, file);
  p.slew_start_s = JsonNumberOr(j, "start_s", p.slew_start_s, file);
  if (j.contains("end_s")) p.slew_end_s = JsonNumber(j, "end_s", file);
  if (p.type == "bench") {
    const MotionProfile campaign = BenchCampaignProfile();
    p.bench = campaign.bench;
    p.temperature = campaign.temperature;
  }
  if (j.contains("bench")) {
    if (!j["bench"].is_array()) throw InputError(file, "field 'bench' must be an array of segments");
    p.bench.clear();
    for (const auto& b : j["bench"]) {
      if (!b.is_object()) throw InputError(file, "bench: each segment must be an object");
      CheckKeys(b, {"duration_s", "up", "table_deg", "rate_dps"}, file + ": bench");
      BenchSegment seg;
      seg.duration_s = JsonNumber(b, "duration_s", file);
      if (b.contains("up")) seg.up_body = Vec3From(b, "up", file);
      seg.table_deg = JsonNumberOr(b, "table_deg", 0, file);
      seg.rate_dps = JsonNumberOr(b, "rate_dps", 0, file);
      p.bench.push_back(seg);
    }
  }
  if (j.contains("axis")) p.axis_body = Vec3From(j, "axis", file);
  if (j.contains("amplitude_dps")) p.amplitude_dps = Vec3From(j, "amplitude_dps", file);
  if (j.contains("periods_s")) p.periods_s = Vec3From(j, "periods_s", file);
  if (j.contains("magnetic_field_ut")) p.magnetic_field_body_ut = Vec3From(j, "magnetic_field_ut", file);
  if (p.type == "static" || p.type == "temperature") {
    p.q0 = StaticAttitude(p.latitude_deg * kDegToRad, p.azimuth_deg * kDegToRad);
  }
  if (j.contains("q0")) {
    const auto q = Numbers(j, "q0", 4, file);
    p.q0 = FromWxyz(q[0], q[1], q[2], q[3], (file + ": q0").c_str());
  }
  if (p.type == "temperature") p.temperature.segments = {{600, 0}, {1200, 0.5}, {600, 0}, {1200, -0.5}};
  if (j.contains("temperature")) {
    const Json& t = j["temperature"];
    CheckKeys(t, {"start_c", "segments"}, file + ": temperature");
    p.temperature.start_c = JsonNumberOr(t, "start_c", 20.0, file);
    p.temperature.segments.clear();
    if (t.contains("segments")) p.temperature.segments = Pairs(t, "segments", file);
  }
  if (j.contains("star_tracker")) {
    const Json& s = j["star_tracker"];
    CheckKeys(s, {"rate_hz", "sigma_cross_arcsec", "sigma_roll_arcsec", "outages_s"}, file + ": star_tracker");
    p.st_rate_hz = JsonNumberOr(s, "rate_hz", p.st_rate_hz, file);
    p.st_sigma_cross_arcsec = JsonNumberOr(s, "sigma_cross_arcsec", p.st_sigma_cross_arcsec, file);
    p.st_sigma_roll_arcsec = JsonNumberOr(s, "sigma_roll_arcsec", p.st_sigma_roll_arcsec, file);
    if (s.contains("outages_s")) p.st_outages_s = Pairs(s, "outages_s", file);
  }
  if (j.contains("faults")) {
    if (!j["faults"].is_array()) throw InputError(file, "field 'faults' must be an array");
    for (const auto& f : j["faults"]) p.faults.push_back(GyroFaultFromJson(f, file));
  }
  return p;
}

MotionProfile BenchCampaignProfile() {
  MotionProfile p;
  p.type = "bench";
  p.latitude_deg = 45.0;
  const Vec3 ups[6] = {Vec3::UnitX(), -Vec3::UnitX(), Vec3::UnitY(), -Vec3::UnitY(), Vec3::UnitZ(), -Vec3::UnitZ()};
  for (const Vec3& up : ups) {
    // Two static positions 180 deg apart: the horizontal Earth rate changes sign, the bias does not.
    p.bench.push_back({120.0, up, 0.0, 0.0});
    p.bench.push_back({120.0, up, 180.0, 0.0});
    // Both signs (asymmetry) at three magnitudes (nonlinearity).
    for (double r : {2.0, -2.0, 10.0, -10.0, 30.0, -30.0}) p.bench.push_back({60.0, up, 0.0, r});
  }
  p.temperature.start_c = 22.0;
  p.temperature.segments = {{900, 0.06}, {900, 0.0}, {900, -0.04}, {900, 0.02}};
  return p;
}

double BenchDurationS(const MotionProfile& p) {
  double d = 0;
  for (const auto& b : p.bench) d += b.duration_s;
  return d;
}

MotionProfile LoadMotionProfile(const std::string& path) { return MotionProfileFromJson(ReadJsonFile(path), path); }

void GyroSimOptions::Check() const {
  if (!(duration_s > 0) || !std::isfinite(duration_s)) throw InputError("simulate gyro", "duration must be positive");
}

GyroSimulation SimulateGyro(const GyroUnit& unit, const MotionProfile& profile, const GyroSimOptions& options) {
  unit.Check("unit");
  profile.Check("profile", unit.size());
  options.Check();
  const int n = unit.size();
  const double h = 1.0 / unit.rate_hz;
  if (options.duration_s * unit.rate_hz > 1e9) throw InputError("simulate gyro", "more than 1e9 samples requested");
  const long k_max = static_cast<long>(std::floor(options.duration_s * unit.rate_hz + 1e-9));
  Rng rng(options.seed);
  Rng rng_st(options.seed * 0x9E3779B97F4A7C15ull + 17);     // own stream: star noise independent of gyros
  Rng rng_fault(options.seed * 0xD1B54A32D192ED03ull + 29);  // and fault noise: a burst leaves the rest alone

  // Per-gyro geometry: misaligned axis and a perpendicular pair (u, v) for the magnetic terms.
  std::vector<Vec3> axis(n), u(n), v(n);
  for (int i = 0; i < n; ++i) {
    const Vec3& a = unit.axes_body[i];
    Eigen::Index m;
    a.cwiseAbs().minCoeff(&m);
    u[i] = a.cross(Vec3::Unit(m)).normalized();
    v[i] = a.cross(u[i]);
    axis[i] = unit.SensingAxis(i);
  }
  // Error-process state; the Gauss-Markov processes start stationary.
  std::vector<std::vector<double>> gm(n);
  std::vector<double> rrw(n, 0.0), quant_acc(n, 0.0), quant_prev(n, 0.0), last_out(n, 0.0);
  for (int i = 0; i < n; ++i) {
    const double s = unit.gyros[i].GaussMarkovSigmaDph();
    for (size_t c = 0; c < unit.gyros[i].bias_instability_tau_s.size(); ++c) gm[i].push_back(s * rng.Normal());
  }
  const RateSolver solver(unit.Axes(), unit.NoiseArw(), std::vector<bool>(n, true));

  GyroSimulation sim;
  sim.q0 = profile.q0.normalized();
  sim.st_sigma_cross_arcsec = profile.st_sigma_cross_arcsec;
  sim.st_sigma_roll_arcsec = profile.st_sigma_roll_arcsec;
  sim.bench_reference = profile.type == "bench";
  sim.t_s.reserve(k_max);
  sim.gyro_dph.reserve(k_max);

  auto star_sample = [&](double t, const Quat& q_true) {
    if (profile.InStarOutage(t)) return;
    const Vec3 noise(profile.st_sigma_cross_arcsec * rng_st.Normal(), profile.st_sigma_cross_arcsec * rng_st.Normal(),
                     profile.st_sigma_roll_arcsec * rng_st.Normal());
    sim.st_t_s.push_back(t);
    sim.st_q.push_back((q_true * QuatFromRotationVector(noise * kArcsecToRad)).normalized());
  };
  const double st_dt = 1.0 / profile.st_rate_hz;
  Quat q = sim.q0;
  star_sample(0.0, q);
  long st_next = 1;

  for (long k = 1; k <= k_max; ++k) {
    const double ta = (k - 1) * h, tb = k * h;
    // Star samples inside (ta, tb]: truth advanced from q(ta) to the sample time.
    while (st_next * st_dt <= tb + 1e-9 * tb) {
      const double ts = st_next * st_dt;
      if (ts > ta) {
        const Quat qs =
            ts - ta > 1e-12 ? (q * QuatFromRotationVector(Integrate(profile, ta, ts).rotation)).normalized() : q;
        star_sample(ts, qs);
      }
      ++st_next;
    }
    q = (q * QuatFromRotationVector(Integrate(profile, ta, tb).rotation)).normalized();
    const double tm = 0.5 * (ta + tb);
    const double temp = profile.temperature.TempC(tm);
    const double temp_rate = profile.temperature.RateCPerMin(tm);
    GyroVec out(n), slow(n);
    for (int i = 0; i < n; ++i) {
      const auto& e = unit.gyros[i];
      const Vec3 inc = Integrate(profile, ta - e.time_delay_s, tb - e.time_delay_s).integral;
      const double w_dph = axis[i].dot(inc) / h * kRadSToDph;
      const double sign = w_dph > 0 ? 1 : w_dph < 0 ? -1 : 0;
      const double sf = 1 + 1e-6 * (e.scale_factor_ppm + e.scale_factor_asymmetry_ppm * sign +
                                    e.scale_factor_nonlinearity_ppm_per_dps * std::abs(w_dph / 3600.0));
      // Slow errors: bias, flicker (Gauss-Markov), rate random walk, temperature, magnetic, faults.
      double err = e.bias_dph;
      const double s = e.GaussMarkovSigmaDph();
      for (size_t c = 0; c < gm[i].size(); ++c) {
        const double phi = std::exp(-h / e.bias_instability_tau_s[c]);
        gm[i][c] = phi * gm[i][c] + s * std::sqrt(1 - phi * phi) * rng.Normal();
        err += gm[i][c];
      }
      rrw[i] += e.rrw_dph_per_sqrt_h / 60.0 * std::sqrt(h) * rng.Normal();
      err += rrw[i];
      err += e.thermal.DriftDph(temp, temp_rate);
      const Vec3& b = profile.magnetic_field_body_ut;
      err += e.magnetic.along_dph_per_ut * b.dot(unit.axes_body[i]) + e.magnetic.across_dph_per_ut * b.dot(u[i]) +
             e.magnetic.vertical_dph_per_ut * b.dot(v[i]);
      bool stuck = false;
      for (const auto& f : profile.faults) {
        if (f.gyro != i + 1 || !f.ActiveAt(tb)) continue;
        err += f.step_dph + f.ramp_dph_per_h * (tb - f.t_s) / 3600.0;
        if (f.noise_dph > 0) err += f.noise_dph * rng_fault.Normal();
        stuck |= f.stuck;
      }
      slow[i] = err;
      // White rate noise of density ARW: sigma = ARW[deg/sqrt(h)] * 60 / sqrt(h[s]) in deg/h.
      double g = sf * w_dph + err + e.arw_deg_per_sqrt_h * 60.0 / std::sqrt(h) * rng.Normal();
      if (e.quantization_arcsec > 0) {
        // The output counter holds whole angle quanta; 1 deg/h over 1 s is 1 arcsec.
        quant_acc[i] += g * h;
        const double counts = std::floor(quant_acc[i] / e.quantization_arcsec);
        g = (counts - quant_prev[i]) * e.quantization_arcsec / h;
        quant_prev[i] = counts;
      }
      if (stuck) g = last_out[i];  // the output register frozen (the error it carries is in the output)
      out[i] = g;
      last_out[i] = g;
    }
    sim.t_s.push_back(tb);
    sim.gyro_dph.push_back(out);
    sim.temp_c.push_back(temp);
    sim.q_true.push_back(q);
    sim.w_true_dph.push_back(profile.RateBodyRadS(tb) * kRadSToDph);
    sim.w_mean_dph.push_back(Integrate(profile, ta, tb).integral / h * kRadSToDph);
    sim.body_bias_dph.push_back(solver.Solve(slow));
  }
  return sim;
}

void WriteGyroSimulation(const std::string& dir, const GyroSimulation& sim, const GyroUnit& unit) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError(dir, "cannot create output directory");
  const int n = unit.size();
  {
    std::vector<std::string> header = {"t_s"};
    for (int i = 1; i <= n; ++i) header.push_back("g" + std::to_string(i) + "_dph");
    header.push_back("temp_c");
    std::vector<std::vector<double>> c(n + 2);
    c[0] = sim.t_s;
    for (size_t k = 0; k < sim.t_s.size(); ++k) {
      for (int i = 0; i < n; ++i) c[1 + i].push_back(sim.gyro_dph[k][i]);
    }
    c[n + 1] = sim.temp_c;
    if (sim.bench_reference) {
      for (int a = 0; a < 3; ++a) {
        header.push_back(std::string("ref_") + "xyz"[a] + "_dph");
        c.emplace_back();
        for (const Vec3& w : sim.w_mean_dph) c.back().push_back(w[a]);
      }
    }
    WriteCsv(dir + "/gyro.csv", header, c);
  }
  auto quats = [](const std::vector<double>& t, const std::vector<Quat>& qs, std::vector<std::vector<double>>* c) {
    c->assign(5, {});
    (*c)[0] = t;
    for (const auto& q : qs) {
      const auto w = ToWxyz(q);
      for (int a = 0; a < 4; ++a) (*c)[1 + a].push_back(w[a]);
    }
  };
  std::vector<std::vector<double>> c;
  quats(sim.t_s, sim.q_true, &c);
  WriteCsv(dir + "/truth.csv", {"t_s", "qw", "qx", "qy", "qz"}, c, 15);
  {
    std::vector<std::vector<double>> r(7);
    r[0] = sim.t_s;
    for (size_t k = 0; k < sim.t_s.size(); ++k) {
      for (int a = 0; a < 3; ++a) r[1 + a].push_back(sim.w_true_dph[k][a]);
      for (int a = 0; a < 3; ++a) r[4 + a].push_back(sim.body_bias_dph[k][a]);
    }
    WriteCsv(dir + "/rates.csv", {"t_s", "wx_dph", "wy_dph", "wz_dph", "bx_dph", "by_dph", "bz_dph"}, r);
  }
  quats(sim.st_t_s, sim.st_q, &c);
  c.push_back(std::vector<double>(sim.st_t_s.size(), sim.st_sigma_cross_arcsec));
  c.push_back(std::vector<double>(sim.st_t_s.size(), sim.st_sigma_roll_arcsec));
  WriteCsv(dir + "/st.csv", {"t_s", "qw", "qx", "qy", "qz", "sigma_cross_arcsec", "sigma_roll_arcsec"}, c, 15);
  WriteJsonFile(dir + "/unit.json", GyroUnitToJson(unit));
}

}  // namespace ssiu
