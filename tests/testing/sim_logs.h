// A simulated gyro run as the logs `ssiu fuse` reads, and the attitude error of a fusion against the
// simulator's truth (header-only: for tests that link the sim and inertial stages).
#pragma once

#include <algorithm>
#include <cmath>

#include "inertial/fuse.h"
#include "inertial/online_fusion.h"
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

// The online fusion (the processor's estimator) over the same logs: each gyro sample, then the star
// fixes up to its time (sigma_cross/roll_arcsec when the log has no sigmas); returns the largest
// attitude error inside [t0, t1] (q_true[k] at log.t_s[k]); with `cal_at_t0`, the unit calibration's
// state at t0.
inline double OnlineWorstErrorArcsec(OnlineFusion* f, const GyroLog& log, const StarTrackerLog& st,
                                     const GyroSimulation& sim, double sigma_cross_arcsec, double sigma_roll_arcsec,
                                     double t0, double t1, UnitCalState* cal_at_t0 = nullptr) {
  double worst = 0;
  size_t j = 0;
  for (size_t k = 0; k < log.t_s.size(); ++k) {
    f->AddGyro(log.t_s[k], log.rates_dph[k]);
    for (; j < st.t_s.size() && st.t_s[j] <= log.t_s[k] + 1e-9; ++j) {
      const double sc = (st.sigma_cross_arcsec.empty() ? sigma_cross_arcsec : st.sigma_cross_arcsec[j]) * kArcsecToRad;
      const double sr = (st.sigma_roll_arcsec.empty() ? sigma_roll_arcsec : st.sigma_roll_arcsec[j]) * kArcsecToRad;
      f->AddAttitude(st.t_s[j], st.q_inertial_from_body[j], Mat3(Vec3(sc * sc, sc * sc, sr * sr).asDiagonal()));
    }
    if (cal_at_t0 && log.t_s[k] >= t0 && (k == 0 || log.t_s[k - 1] < t0)) *cal_at_t0 = f->unit_calibration();
    if (log.t_s[k] < t0 || log.t_s[k] > t1 || !f->initialised()) continue;
    const Quat d = f->q() * sim.q_true[k].conjugate();
    worst = std::max(worst, 2 * std::asin(std::min(1.0, d.vec().norm())) * kRadToArcsec);
  }
  return worst;
}

}  // namespace ssiu::testing
