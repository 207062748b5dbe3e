// The unit bench calibration Monte Carlo shared by fog_unit_test (a few seeds) and fog_unit_longtest
// (20): simulated campaigns with unit errors drawn at realistic levels, scored against the truth the
// simulator used; and the slew through a star outage fused with the nominal and the calibrated unit.
#pragma once

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "calibration/fog_unit.h"
#include "core/rng.h"
#include "inertial/fuse.h"
#include "sim/gyro_sim.h"
#include "testing/sim_logs.h"

namespace ssiu {

struct UnitCampaign {
  GyroUnit truth, nominal;
  UnitCalibrationResult fit;
};

// Unit errors per gyro: |scale| 10-300 ppm, misalignment 0.5-5 arcmin in a random direction, bias
// +-(0.5-3) deg/h, ARW 0.005-0.02 deg/sqrt(h), bias instability 0.02-0.08 deg/h, temperature drift
// K00 +-0.2, K10 +-0.8, K01 +-0.3 deg/h (eq. (1)); scale-factor asymmetry 20-100 ppm on some gyros and
// nonlinearity 0.5-3 ppm per deg/s on others. The nominal unit has the nominal axes and the same noise
// figures (what an Allan analysis of the unit gives before the campaign).
inline UnitCampaign MakeUnitCampaign(uint64_t seed, double rate_hz) {
  Rng rng(seed * 7919 + 11);
  auto sign = [&] { return rng.Uniform() < 0.5 ? -1.0 : 1.0; };
  UnitCampaign c;
  c.nominal = DefaultFourFogUnit();
  c.nominal.rate_hz = rate_hz;
  c.truth = c.nominal;
  for (int i = 0; i < c.truth.size(); ++i) {
    GyroErrorModel& e = c.truth.gyros[i];
    e.arw_deg_per_sqrt_h = rng.Uniform(0.005, 0.02);
    e.bias_instability_dph = rng.Uniform(0.02, 0.08);
    c.nominal.gyros[i].arw_deg_per_sqrt_h = e.arw_deg_per_sqrt_h;
    c.nominal.gyros[i].bias_instability_dph = e.bias_instability_dph;
    e.scale_factor_ppm = sign() * rng.Uniform(10, 300);
    const double mis = rng.Uniform(0.5, 5) * 60, dir = rng.Uniform(0, 2 * kPi);
    e.misalignment_arcsec[0] = mis * std::cos(dir);
    e.misalignment_arcsec[1] = mis * std::sin(dir);
    e.bias_dph = sign() * rng.Uniform(0.5, 3);
    e.thermal.k_dph[0] = rng.Uniform(-0.2, 0.2);
    e.thermal.k_dph[1] = rng.Uniform(-0.8, 0.8);
    e.thermal.k_dph[2] = rng.Uniform(-0.3, 0.3);
    const double u = rng.Uniform();
    if (u < 0.3) e.scale_factor_asymmetry_ppm = sign() * rng.Uniform(20, 100);
    if (u > 0.7) e.scale_factor_nonlinearity_ppm_per_dps = sign() * rng.Uniform(0.5, 3);
  }
  GyroSimOptions so;
  so.seed = seed;
  const MotionProfile bench = BenchCampaignProfile();
  so.duration_s = BenchDurationS(bench);
  const GyroSimulation sim = SimulateGyro(c.truth, bench, so);
  UnitBenchLog log;
  log.file = "campaign";
  log.t_s = sim.t_s;
  log.temp_c = sim.temp_c;
  log.ref_dph = sim.w_mean_dph;
  log.g_dph.assign(c.truth.size(), {});
  for (const auto& g : sim.gyro_dph) {
    for (int i = 0; i < c.truth.size(); ++i) log.g_dph[i].push_back(g[i]);
  }
  c.fit = CalibrateUnit({log}, c.nominal, UnitCalibrationOptions{});
  return c;
}

struct UnitCalScore {
  int parameters = 0, within_3sigma = 0;
  int nees_count = 0;
  double nees_sum = 0;  // of the 4-vector (bias, scale, two tilts) per gyro
  std::string failures;
  double Fraction() const { return parameters ? static_cast<double>(within_3sigma) / parameters : 0; }
  double MeanNees() const { return nees_count ? nees_sum / nees_count : 0; }
  std::string Describe() const {
    std::ostringstream s;
    s << within_3sigma << "/" << parameters << " parameters within 3 sigma, mean NEES " << MeanNees() << " over "
      << nees_count << " gyros (4 dof)" << failures;
    return s.str();
  }
};

// The truth of each fitted parameter: the bias at the reference temperature (G = 0) and the tilts of
// the simulator's sensing axis from the nominal one, projected as the fit reports them.
inline void ScoreUnitCampaign(const UnitCampaign& c, UnitCalScore* s) {
  for (int i = 0; i < c.truth.size(); ++i) {
    const GyroErrorModel& e = c.truth.gyros[i];
    const GyroCalibration& g = c.fit.gyros[i];
    const Vec3 n = c.nominal.axes_body[i], a = c.truth.SensingAxis(i);
    Eigen::Index m;
    n.cwiseAbs().minCoeff(&m);
    const Vec3 u = n.cross(Vec3::Unit(m)).normalized(), v = n.cross(u);
    Eigen::Vector4d err;
    err << g.bias_dph - (e.bias_dph + e.thermal.DriftDph(c.fit.temp_ref_c, 0)), g.scale_factor_ppm - e.scale_factor_ppm,
        g.misalignment_arcsec[0] - a.dot(u) / a.dot(n) * kRadToArcsec,
        g.misalignment_arcsec[1] - a.dot(v) / a.dot(n) * kRadToArcsec;
    const char* names[4] = {"bias", "scale", "mis_u", "mis_v"};
    for (int k = 0; k < 4; ++k) {
      ++s->parameters;
      const double z = err[k] / std::sqrt(g.cov(k, k));
      if (std::abs(z) <= 3) {
        ++s->within_3sigma;
      } else {
        s->failures += "\n  gyro " + std::to_string(i + 1) + " " + names[k] + " z=" + std::to_string(z);
      }
    }
    // Asymmetry and nonlinearity where the selection kept them.
    for (const auto& t : g.terms) {
      double truth = 0;
      if (t.name == "scale_factor_asymmetry")
        truth = e.scale_factor_asymmetry_ppm;
      else if (t.name == "scale_factor_nonlinearity")
        truth = e.scale_factor_nonlinearity_ppm_per_dps;
      else
        continue;
      if (!t.kept) continue;
      ++s->parameters;
      const double z = (t.estimate - truth) / t.sigma;
      if (std::abs(z) <= 3) {
        ++s->within_3sigma;
      } else {
        s->failures += "\n  gyro " + std::to_string(i + 1) + " " + t.name + " z=" + std::to_string(z);
      }
    }
    s->nees_sum += err.dot(g.cov.ldlt().solve(err));
    ++s->nees_count;
  }
}

// The slew axis of a seed's outage case: a random direction in the body.
inline Vec3 SlewAxisForSeed(uint64_t seed) {
  Rng rng(seed * 104729 + 3);
  return Vec3(rng.Normal(), rng.Normal(), rng.Normal()).normalized();
}

// A spacecraft at rest for 600 s with star fixes, then a 1 deg/s slew about a fixed body axis for
// 300 s through a star outage of the same 300 s, then stars again. The largest attitude error
// (arcsec) during the outage when the truth unit's output is fused with `processor_unit`.
inline double OutageErrorArcsec(const GyroUnit& truth, const GyroUnit& processor_unit, uint64_t seed,
                                const Vec3& slew_axis) {
  MotionProfile p;
  p.type = "slew";
  p.rate_dps = 1.0;
  p.axis_body = slew_axis;
  p.slew_start_s = 600;
  p.slew_end_s = 900;
  p.st_outages_s = {{600, 900}};
  p.q0 = Quat(Eigen::AngleAxisd(0.7, Vec3(0.2, 0.5, -0.3).normalized()));
  GyroSimOptions so;
  so.seed = seed + 1000;
  so.duration_s = 960;
  const GyroSimulation sim = SimulateGyro(truth, p, so);
  return testing::WorstErrorArcsec(
      Fuse(testing::GyroLogOf(sim), testing::StarLogOf(sim), processor_unit, FuseOptions{}), sim, truth.rate_hz, 600,
      900);
}

}  // namespace ssiu
