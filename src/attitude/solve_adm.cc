#include "attitude/solve_adm.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/stats.h"

namespace ssiu {
namespace {

double SecondsBetween(const UtcTime& from, const UtcTime& to) {
  return ((to.tt_jd1 - from.tt_jd1) + (to.tt_jd2 - from.tt_jd2)) * 86400.0;
}

}  // namespace

AttitudeHistory SolvedAttitudeHistory(std::vector<TimedAttitude> solutions, const std::string& where, int head) {
  solutions.erase(std::remove_if(solutions.begin(), solutions.end(),
                                 [](const TimedAttitude& s) { return s.attitude.status != SolveStatus::kSolved; }),
                  solutions.end());
  if (solutions.empty()) throw InputError(where, "no solved frame: no attitude history to write");
  for (const TimedAttitude& s : solutions)
    if (!s.time.valid())
      throw InputError(where, "a solved frame has no time (give --time, or FITS frames with DATE-OBS)");
  std::sort(solutions.begin(), solutions.end(),
            [](const TimedAttitude& a, const TimedAttitude& b) { return SecondsBetween(b.time, a.time) < 0; });
  AttitudeHistory h;
  // The epoch as text to the millisecond; every t_s counts from that text's instant.
  h.epoch_utc = FormatUtcIso8601(solutions.front().time);
  const UtcTime epoch = ParseUtcIso8601(h.epoch_utc, where);
  h.body_frame = "AST_" + std::to_string(head);
  h.basis = "DETERMINED_GND";
  h.cov_type = "ANGLE";
  std::vector<double> cross, roll, t;
  for (const TimedAttitude& s : solutions) {
    AdmState a;
    a.t_s = SecondsBetween(epoch, s.time);
    if (!h.states.empty() && !(a.t_s > h.states.back().t_s + 1e-6))
      throw InputError(where, "two solved frames at the same time " + FormatUtcIso8601(s.time) +
                                  " (each frame needs its own time: DATE-OBS, or --dt-s)");
    a.q_inertial_from_body = s.attitude.q_inertial_from_sensor;
    h.states.push_back(a);
    const Vec3 d = s.attitude.covariance_rad2.diagonal();
    h.covariances.push_back({a.t_s, {d.x(), d.y(), d.z()}});
    cross.push_back(s.attitude.sigma_cross_rad);
    roll.push_back(s.attitude.sigma_roll_rad);
    t.push_back(a.t_s);
  }
  AdmDetermination ad;
  ad.method = "QUEST";
  AdmSensor sensor{1, h.body_frame, {Median(cross), Median(cross), Median(roll)}, 0.0};
  std::vector<double> dt;
  for (size_t k = 1; k < t.size(); ++k) dt.push_back(t[k] - t[k - 1]);
  if (!dt.empty() && Median(dt) > 0) sensor.rate_hz = 1.0 / Median(dt);
  ad.sensors.push_back(sensor);
  h.determination = ad;
  return h;
}

}  // namespace ssiu
