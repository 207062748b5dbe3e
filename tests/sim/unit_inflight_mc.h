// In-flight calibration (`ssiu fuse --calibrate-unit`) on simulated slewing missions, shared by
// unit_inflight_test (a few seeds) and unit_inflight_longtest (20): the unit's errors drawn at the bench
// campaign's levels, a mission turning about all three axes (1 deg/s sines of different periods) with a
// 5-minute star outage, fused with the nominal unit and with the unit calibrated from the same log; and
// the processor's estimator (OnlineFusion with FuseOptions::calibrate_unit) run through the same log,
// its state at the outage's start scored and its outage error against the same estimator without it.
#pragma once

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "core/rng.h"
#include "inertial/fuse.h"
#include "inertial/online_fusion.h"
#include "inertial/unit_inflight.h"
#include "sim/gyro_sim.h"
#include "testing/sim_logs.h"

namespace ssiu::testing {

struct InflightScore {
  int parameters = 0, within_3sigma = 0, nees_count = 0;
  double nees_sum = 0;  // of (scale, two tilts) per gyro
  double nominal2 = 0, calibrated2 = 0;
  int cases = 0;
  // The online estimator: its estimates at the outage's start, and the outage errors with and without.
  int online_parameters = 0, online_within_3sigma = 0, online_applied = 0;
  double online_nees_sum = 0, online_nominal2 = 0, online_calibrated2 = 0;
  std::string failures;
  double Fraction() const { return parameters ? double(within_3sigma) / parameters : 0; }
  double MeanNees() const { return nees_count ? nees_sum / nees_count : 0; }
  double OnlineMeanNees() const { return online_parameters ? 3 * online_nees_sum / online_parameters : 0; }
  std::string Describe() const {
    std::ostringstream s;
    s << within_3sigma << "/" << parameters << " within 3 sigma, mean NEES " << MeanNees() << " (3 dof, " << nees_count
      << " gyros); outage error RMS nominal " << std::sqrt(nominal2 / std::max(1, cases)) << " arcsec, calibrated "
      << std::sqrt(calibrated2 / std::max(1, cases)) << "; online: " << online_within_3sigma << "/" << online_parameters
      << " within 3 sigma, mean NEES " << OnlineMeanNees() << ", applied in " << online_applied << "/" << cases
      << ", outage error RMS without " << std::sqrt(online_nominal2 / std::max(1, cases)) << " arcsec, with "
      << std::sqrt(online_calibrated2 / std::max(1, cases)) << failures;
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
  // One gyro's (scale factor, two tilts) against the truth: counted, NEES summed, misses listed.
  auto score = [&](const char* who, int i, const double est[3], const double sig[3], int* parameters, int* within,
                   double* nees_sum) {
    const GyroErrorModel& e = truth.gyros[i];
    const double truth3[3] = {e.scale_factor_ppm, e.misalignment_arcsec[0], e.misalignment_arcsec[1]};
    for (int k = 0; k < 3; ++k) {
      ++*parameters;
      const double z = (est[k] - truth3[k]) / sig[k];
      *nees_sum += z * z;
      if (std::abs(z) <= 3) {
        ++*within;
      } else {
        s->failures += "\n  seed " + std::to_string(seed) + who + " gyro " + std::to_string(i + 1) + " param " +
                       std::to_string(k) + " z=" + std::to_string(z);
      }
    }
  };
  for (int i = 0; i < 4; ++i) {
    const InflightGyroCal& g = c.gyros[i];
    const double est[3] = {g.scale_factor_ppm, g.misalignment_arcsec[0], g.misalignment_arcsec[1]};
    const double sig[3] = {g.scale_factor_sigma_ppm, g.misalignment_sigma_arcsec[0], g.misalignment_sigma_arcsec[1]};
    score("", i, est, sig, &s->parameters, &s->within_3sigma, &s->nees_sum);
    ++s->nees_count;
  }
  const double nominal_err = WorstErrorArcsec(Fuse(log, st, nominal, FuseOptions{}), sim, 10, t_out, t_back);
  const double calibrated_err = WorstErrorArcsec(Fuse(log, st, c.unit, FuseOptions{}), sim, 10, t_out, t_back);
  s->nominal2 += nominal_err * nominal_err;
  s->calibrated2 += calibrated_err * calibrated_err;
  ++s->cases;

  // The processor's estimator: scored at the outage's start (what it knows when the stars go).
  FuseOptions on;
  on.calibrate_unit = true;
  OnlineFusion with(nominal, on), without(nominal, FuseOptions{});
  UnitCalState cal;
  const double online_err = OnlineWorstErrorArcsec(&with, log, st, sim, 5, 30, t_out, t_back, &cal);
  const double online_nominal_err = OnlineWorstErrorArcsec(&without, log, st, sim, 5, 30, t_out, t_back);
  s->online_calibrated2 += online_err * online_err;
  s->online_nominal2 += online_nominal_err * online_nominal_err;
  if (cal.status == UnitCalStatus::kApplied) ++s->online_applied;
  for (int i = 0; i < 4 && cal.status >= UnitCalStatus::kEstimated; ++i) {
    const double est[3] = {cal.scale_factor_ppm[i], cal.misalignment_arcsec[i][0], cal.misalignment_arcsec[i][1]};
    const double sig[3] = {cal.scale_factor_sigma_ppm[i], cal.misalignment_sigma_arcsec[i][0],
                           cal.misalignment_sigma_arcsec[i][1]};
    score(" online", i, est, sig, &s->online_parameters, &s->online_within_3sigma, &s->online_nees_sum);
  }
}

}  // namespace ssiu::testing
