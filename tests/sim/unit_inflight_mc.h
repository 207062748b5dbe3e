// In-flight calibration (`ssiu fuse --calibrate-unit`) on simulated slewing missions, shared by
// unit_inflight_test (a few seeds) and unit_inflight_longtest (20): the unit's errors drawn at the bench
// campaign's levels, a mission turning about all three axes (1 deg/s sines of different periods) with a
// 5-minute star outage, fused with the nominal unit and with the unit calibrated from the same log.
#pragma once

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "core/rng.h"
#include "inertial/fuse.h"
#include "inertial/unit_inflight.h"
#include "sim/gyro_sim.h"
#include "testing/sim_logs.h"

namespace ssiu::testing {

struct InflightScore {
  int parameters = 0, within_3sigma = 0, nees_count = 0;
  double nees_sum = 0;  // of (scale, two tilts) per gyro
  double nominal2 = 0, calibrated2 = 0;
  int cases = 0;
  std::string failures;
  double Fraction() const { return parameters ? double(within_3sigma) / parameters : 0; }
  double MeanNees() const { return nees_count ? nees_sum / nees_count : 0; }
  std::string Describe() const {
    std::ostringstream s;
    s << within_3sigma << "/" << parameters << " within 3 sigma, mean NEES " << MeanNees() << " (3 dof, " << nees_count
      << " gyros); outage error RMS nominal " << std::sqrt(nominal2 / std::max(1, cases)) << " arcsec, calibrated "
      << std::sqrt(calibrated2 / std::max(1, cases)) << failures;
    return s.str();
  }
};

inline void RunInflightCase(uint64_t seed, InflightScore* s) {
  Rng rng(seed * 6007 + 5);
  auto sign = [&] { return rng.Uniform() < 0.5 ? -1.0 : 1.0; };
  GyroUnit nominal = DefaultFourFogUnit();
  nominal.rate_hz = 10;
  GyroUnit truth = nominal;
  for (int i = 0; i < 4; ++i) {
    GyroErrorModel& e = truth.gyros[i];
    e.arw_deg_per_sqrt_h = nominal.gyros[i].arw_deg_per_sqrt_h = rng.Uniform(0.005, 0.02);
    e.bias_instability_dph = nominal.gyros[i].bias_instability_dph = rng.Uniform(0.02, 0.08);
    e.scale_factor_ppm = sign() * rng.Uniform(10, 300);
    const double mis = rng.Uniform(0.5, 5) * 60, dir = rng.Uniform(0, 2 * kPi);
    e.misalignment_arcsec[0] = mis * std::cos(dir), e.misalignment_arcsec[1] = mis * std::sin(dir);
    e.bias_dph = sign() * rng.Uniform(0.5, 3);
  }
  MotionProfile p;
  p.type = "sine";
  p.amplitude_dps = Vec3(1, 1, 1);
  p.periods_s = Vec3(rng.Uniform(240, 600), rng.Uniform(240, 600), rng.Uniform(240, 600));
  p.q0 = Quat(Eigen::AngleAxisd(rng.Uniform(0, 3), Vec3(rng.Normal(), rng.Normal(), rng.Normal()).normalized()));
  const double t_out = 3000, t_back = 3300;
  p.st_outages_s = {{t_out, t_back}};
  GyroSimOptions so;
  so.seed = seed;
  so.duration_s = 3600;
  const GyroSimulation sim = SimulateGyro(truth, p, so);
  const GyroLog log = GyroLogOf(sim);
  const StarTrackerLog st = StarLogOf(sim);
  const InflightCalResult c = CalibrateUnitInFlight(log, st, nominal, 5, 30, InflightCalOptions{});
  if (!c.ok) {
    s->failures += "\n  seed " + std::to_string(seed) + ": " + c.message;
    return;
  }
  for (int i = 0; i < 4; ++i) {
    const GyroErrorModel& e = truth.gyros[i];
    const InflightGyroCal& g = c.gyros[i];
    const double err[3] = {g.scale_factor_ppm - e.scale_factor_ppm, g.misalignment_arcsec[0] - e.misalignment_arcsec[0],
                           g.misalignment_arcsec[1] - e.misalignment_arcsec[1]};
    const double sig[3] = {g.scale_factor_sigma_ppm, g.misalignment_sigma_arcsec[0], g.misalignment_sigma_arcsec[1]};
    for (int k = 0; k < 3; ++k) {
      ++s->parameters;
      const double z = err[k] / sig[k];
      s->nees_sum += z * z;
      if (std::abs(z) <= 3) {
        ++s->within_3sigma;
      } else {
        s->failures += "\n  seed " + std::to_string(seed) + " gyro " + std::to_string(i + 1) + " param " +
                       std::to_string(k) + " z=" + std::to_string(z);
      }
    }
    ++s->nees_count;
  }
  const double nominal_err = WorstErrorArcsec(Fuse(log, st, nominal, FuseOptions{}), sim, 10, t_out, t_back);
  const double calibrated_err = WorstErrorArcsec(Fuse(log, st, c.unit, FuseOptions{}), sim, 10, t_out, t_back);
  s->nominal2 += nominal_err * nominal_err;
  s->calibrated2 += calibrated_err * calibrated_err;
  ++s->cases;
}

}  // namespace ssiu::testing
