#include "sim/fog_bench_sim.h"

#include <algorithm>
#include <cmath>

#include "core/csv.h"
#include "core/error.h"
#include "core/rng.h"
#include "core/types.h"

namespace ssiu {
namespace {

void Require(bool ok, const std::string& what) {
  if (!ok) throw InputError("options", what);
}

// First-order Gauss-Markov process sampled every dt: x' = a x + sigma sqrt(1 - a^2) n.
class GaussMarkov {
 public:
  GaussMarkov(double sigma, double tau_s, double dt_s, Rng* rng)
      : a_(tau_s > 0 ? std::exp(-dt_s / tau_s) : 0.0), sigma_(sigma), rng_(rng) {
    x_ = sigma_ * rng_->Normal();
  }
  double Next() {
    const double v = x_;
    x_ = a_ * x_ + sigma_ * std::sqrt(1 - a_ * a_) * rng_->Normal();
    return v;
  }

 private:
  double a_, sigma_, x_;
  Rng* rng_;
};

}  // namespace

double EarthRateOnAxisDph(double latitude_deg, const std::string& axis) {
  const double lat = latitude_deg * kDegToRad;
  if (axis == "up") return kEarthRateDph * std::sin(lat);
  if (axis == "down") return -kEarthRateDph * std::sin(lat);
  if (axis == "north") return kEarthRateDph * std::cos(lat);
  if (axis == "south") return -kEarthRateDph * std::cos(lat);
  if (axis == "east" || axis == "west") return 0.0;
  throw InputError("--axis", "unknown axis '" + axis + "' (up, down, north, south, east, west)");
}

void ThermalBenchOptions::Check() const {
  Require(duration_s > 0 && dt_s > 0 && duration_s >= 10 * dt_s, "duration_s and dt_s must be positive");
  // A bound on the log's length, as for `simulate gyro`: 1e12 s ran (and wrote) for hours.
  Require(duration_s / dt_s <= 5e7, "duration_s / dt_s must be at most 5e7 samples");
  Require(temp_max_c > temp_min_c, "temp_max_c must exceed temp_min_c");
  Require(min_rate_c_per_min > 0 && max_rate_c_per_min >= min_rate_c_per_min, "bad ramp rates");
  Require(dwell_min_s >= 0 && dwell_max_s >= dwell_min_s, "bad dwell durations");
  Require(chamber_tau_s > 0, "chamber_tau_s must be positive");
  Require(temp_noise_c >= 0 && white_noise_dph >= 0 && wander_sigma_dph >= 0 && wander_tau_s > 0,
          "noise levels must be non-negative");
}

ThermalBenchRun SimulateThermalRun(const ThermalBenchOptions& o) {
  o.Check();
  Rng rng(o.seed);
  // Set-point programme: knots (time, temperature), alternating dwell and ramp.
  std::vector<double> knot_t{0.0}, knot_c{o.temp_min_c + 0.1 * (o.temp_max_c - o.temp_min_c) * rng.Uniform()};
  const double span = o.temp_max_c - o.temp_min_c;
  while (knot_t.back() < o.duration_s) {
    const double dwell = rng.Uniform(o.dwell_min_s, o.dwell_max_s);
    knot_t.push_back(knot_t.back() + dwell);
    knot_c.push_back(knot_c.back());
    double target;
    do {
      target = rng.Uniform(o.temp_min_c, o.temp_max_c);
    } while (std::abs(target - knot_c.back()) < 0.3 * span);
    const double rate_c_per_s = rng.Uniform(o.min_rate_c_per_min, o.max_rate_c_per_min) / 60.0;
    knot_t.push_back(knot_t.back() + std::abs(target - knot_c.back()) / rate_c_per_s);
    knot_c.push_back(target);
  }
  auto set_point = [&](double t) {
    const auto it = std::upper_bound(knot_t.begin(), knot_t.end(), t);
    if (it == knot_t.end()) return knot_c.back();
    const size_t k = it - knot_t.begin();
    const double f = (t - knot_t[k - 1]) / (knot_t[k] - knot_t[k - 1]);
    return knot_c[k - 1] + f * (knot_c[k] - knot_c[k - 1]);
  };

  ThermalBenchRun run;
  const size_t n = static_cast<size_t>(std::floor(o.duration_s / o.dt_s)) + 1;
  const double ref = EarthRateOnAxisDph(o.latitude_deg, o.axis);
  GaussMarkov wander(o.wander_sigma_dph, o.wander_tau_s, o.dt_s, &rng);
  double temp = knot_c.front();
  const double decay = std::exp(-o.dt_s / o.chamber_tau_s);
  for (size_t i = 0; i < n; ++i) {
    const double t = i * o.dt_s;
    const double sp = set_point(t);
    const double rate_c_per_min = (sp - temp) / o.chamber_tau_s * 60.0;  // T' = (s - T)/tau
    const double drift = o.drift.DriftDph(temp, rate_c_per_min);
    run.t_s.push_back(t);
    run.ref_dph.push_back(ref);
    run.w_dph.push_back(ref + drift + wander.Next() + o.white_noise_dph * rng.Normal());
    run.temp_c.push_back(temp + o.temp_noise_c * rng.Normal());
    run.true_temp_c.push_back(temp);
    run.true_rate_c_per_min.push_back(rate_c_per_min);
    run.true_drift_dph.push_back(drift);
    // Exact step of the first-order lag for a set point linear over the step.
    const double r = (set_point(t + o.dt_s) - sp) / o.dt_s;
    temp = set_point(t + o.dt_s) - r * o.chamber_tau_s + (temp - sp + r * o.chamber_tau_s) * decay;
  }
  return run;
}

void WriteThermalRunCsv(const std::string& path, const ThermalBenchRun& run, bool with_truth) {
  std::vector<std::string> header{"t_s", "w_dph", "ref_dph", "temp_c"};
  std::vector<std::vector<double>> cols{run.t_s, run.w_dph, run.ref_dph, run.temp_c};
  if (with_truth) {
    header.insert(header.end(), {"true_temp_c", "true_rate_c_per_min", "true_drift_dph"});
    cols.insert(cols.end(), {run.true_temp_c, run.true_rate_c_per_min, run.true_drift_dph});
  }
  WriteCsv(path, header, cols, 10);
}

ThermalDriftModel CampaignDriftModel() {
  ThermalDriftModel m;
  m.k_dph[0] = -0.60;  // K00
  m.k_dph[1] = 1.20;   // K10
  m.k_dph[2] = 0.55;   // K01
  m.k_dph[9] = 0.30;   // K03
  return m;
}

void TurntableOptions::Check() const {
  Require(positions >= 1 && dwell_s > 0 && turn_s >= 0 && dt_s > 0, "bad turntable timing");
  Require(positions <= 3600 && positions * (dwell_s + turn_s) / dt_s <= 5e7,
          "positions must be at most 3600 and the log at most 5e7 samples");
  Require(std::abs(latitude_deg) < 90, "latitude_deg must be within (-90, 90)");
  Require(std::isfinite(dpsi0_deg), "dpsi0_deg must be finite");
  Require(white_noise_dph >= 0 && wander_sigma_dph >= 0 && wander_tau_s > 0, "bad noise levels");
}

TurntableLog SimulateTurntable(const TurntableOptions& o) {
  o.Check();
  Rng rng(o.seed);
  const double w_phi = kEarthRateDph * std::cos(o.latitude_deg * kDegToRad);
  GaussMarkov wander_x(o.wander_sigma_dph, o.wander_tau_s, o.dt_s, &rng);
  GaussMarkov wander_y(o.wander_sigma_dph, o.wander_tau_s, o.dt_s, &rng);
  TurntableLog log;
  const double period = o.dwell_s + o.turn_s;
  const double total = o.positions * o.dwell_s + (o.positions - 1) * o.turn_s;
  for (double t = 0; t <= total + 1e-9; t += o.dt_s) {
    const int k = std::min(o.positions - 1, static_cast<int>(std::floor(t / period)));
    const double in_seg = t - k * period;
    double az_deg, since_turn_s;
    if (in_seg <= o.dwell_s || k == o.positions - 1) {
      az_deg = k * o.step_deg;
      since_turn_s = k == 0 ? 1e9 : in_seg;
    } else {  // turning to the next position
      az_deg = (k + (in_seg - o.dwell_s) / o.turn_s) * o.step_deg;
      since_turn_s = 0;
    }
    // True azimuth of the FOGX axis from north (towards east); FOGY's axis is 90 deg behind.
    const double psi = (az_deg + o.dpsi0_deg) * kDegToRad;
    const double c = std::cos(psi), s = std::sin(psi);
    const double along_x = o.bn_ut * c + o.be_ut * s, across_x = -o.bn_ut * s + o.be_ut * c;
    const double along_y = o.bn_ut * s - o.be_ut * c, across_y = o.bn_ut * c + o.be_ut * s;
    const double mag_x = o.fog_x.along_dph_per_ut * along_x + o.fog_x.across_dph_per_ut * across_x +
                         o.fog_x.vertical_dph_per_ut * o.bv_ut;
    const double mag_y = o.fog_y.along_dph_per_ut * along_y + o.fog_y.across_dph_per_ut * across_y +
                         o.fog_y.vertical_dph_per_ut * o.bv_ut;
    const double transient = o.transient_dph * std::exp(-since_turn_s / o.transient_tau_s);
    log.t_s.push_back(t);
    log.azimuth_deg.push_back(az_deg);
    log.wx_dph.push_back(w_phi * c + o.bias_x_dph + mag_x + transient + wander_x.Next() +
                         o.white_noise_dph * rng.Normal());
    log.wy_dph.push_back(w_phi * s + o.bias_y_dph + mag_y - transient + wander_y.Next() +
                         o.white_noise_dph * rng.Normal());
    log.temp_c.push_back(o.temp_c + 0.02 * rng.Normal());
  }
  return log;
}

void WriteTurntableCsv(const std::string& path, const TurntableLog& log) {
  WriteCsv(path, {"t_s", "wx_dph", "wy_dph", "azimuth_deg", "temp_c"},
           {log.t_s, log.wx_dph, log.wy_dph, log.azimuth_deg, log.temp_c}, 10);
}

}  // namespace ssiu
