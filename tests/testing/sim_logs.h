// A simulated gyro run as the logs `ssiu fuse` reads, and the attitude error of a fusion against the
// simulator's truth (header-only: for tests that link the sim and inertial stages).
#pragma once

#include <algorithm>
#include <cmath>

#include "inertial/fuse.h"
#include "sim/gyro_sim.h"

namespace ssiu::testing {

inline GyroLog GyroLogOf(const GyroSimulation& sim) {
  GyroLog log;
  log.file = "sim";
  log.t_s = sim.t_s;
  log.rates_dph = sim.gyro_dph;
  return log;
}

inline StarTrackerLog StarLogOf(const GyroSimulation& sim) {
  StarTrackerLog st;
  st.file = "sim";
  st.t_s = sim.st_t_s;
  st.q_inertial_from_body = sim.st_q;
  return st;
}

// Largest attitude error (arcsec, rotation angle of q_est * conj(q_true)) of a fusion inside [t0, t1];
// fused samples on the simulation's gyro times (rate_hz).
inline double WorstErrorArcsec(const FuseResult& r, const GyroSimulation& sim, double rate_hz, double t0, double t1) {
  double worst = 0;
  for (const auto& f : r.samples) {
    if (f.t_s < t0 || f.t_s > t1) continue;
    const long k = std::lround(f.t_s * rate_hz) - 1;
    if (k < 0 || k >= static_cast<long>(sim.q_true.size())) continue;
    const Quat d = f.q_inertial_from_body * sim.q_true[k].conjugate();
    worst = std::max(worst, 2 * std::asin(std::min(1.0, d.vec().norm())) * kRadToArcsec);
  }
  return worst;
}

}  // namespace ssiu::testing
