// Issue 16 acceptance sweep (label `long`, not in CI): steps of 5-2000 deg/h and ramps of 1-100 deg/h
// per second on each of the four gyros, and two faults in sequence (a ramp then a step; a step then
// ramps of 0.5-10 deg/h per s), on a gyro + star-tracker log
// (100 Hz FOGs, 1 Hz star tracker, 300 s slew, fault at 100 s; the second at 200 s). For each: the
// fused attitude is within its reported 3 sigma, or the status is not ok, at least 99% of the time;
// the faulty gyro is isolated. The table (detection and isolation delays) is in docs/results.md.
#include <cmath>
#include <cstdio>
#include <string>

#include "sim/gyro_fusion_scenario.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

struct Case {
  std::string name;
  std::vector<GyroFault> faults;
  double min_trust = 0.99;  // the acceptance
};

struct Outcome {
  double trust = 0, bad_s = 0, first_bad = -1, last_bad = -1;
  bool isolated_right = true;
};

Outcome RunCase(const Case& c, uint64_t seed) {
  testing::FusionScenario sc;
  sc.rate_hz = 100;
  sc.duration_s = 300;
  sc.seed = seed;
  sc.faults = c.faults;
  const auto s = testing::RunFusionScenario(sc, 300.0);
  Outcome o;
  o.trust = testing::TrustworthyFraction(s, 10.0, &o.bad_s, &o.first_bad, &o.last_bad);
  std::string line;
  char b[200];
  // One event per injected fault: a ramp followed on three gyros must not split into several.
  o.isolated_right = s.fused.faults.size() == c.faults.size();
  for (size_t i = 0; i < c.faults.size(); ++i) {
    if (i >= s.fused.faults.size()) {
      o.isolated_right = false;
      line += " | not detected";
      continue;
    }
    const FaultEvent& f = s.fused.faults[i];
    o.isolated_right &= f.gyro == c.faults[i].gyro && f.status == FaultStatus::kIsolated;
    std::snprintf(b, sizeof b, " | g%d %s: onset %+.2f s, detect +%.2f s (%s), isolate +%.2f s, %s %.1f (ramp %.2f)",
                  f.gyro, FaultStatusName(f.status), f.t_onset_s - c.faults[i].t_s, f.t_detect_s - c.faults[i].t_s,
                  f.test.c_str(), f.t_isolate_s >= 0 ? f.t_isolate_s - c.faults[i].t_s : -1.0, f.shape.c_str(),
                  f.fault_dph, f.ramp_dph_per_s);
    line += b;
  }
  std::printf("%-30s trustworthy %6.2f%% (ok outside 3 sigma %.2f s, %.1f-%.1f s), status %s%s\n", c.name.c_str(),
              100 * o.trust, o.bad_s, o.first_bad, o.last_bad, FuseStatusName(s.fused.status), line.c_str());
  return o;
}

TEST(GyroFaultSweep, StepsRampsAndSequencesOnEveryGyroStayTrustworthy) {
  std::vector<Case> cases;
  for (int g = 1; g <= 4; ++g) {
    for (double step : {5.0, 20.0, 100.0, 500.0, 2000.0}) {
      cases.push_back({"gyro " + std::to_string(g) + " step " + std::to_string(static_cast<int>(step)) + " dph",
                       {GyroFault{g, 100.0, step, 0.0}}});
    }
    for (double ramp : {1.0, 10.0, 100.0}) {
      cases.push_back({"gyro " + std::to_string(g) + " ramp " + std::to_string(static_cast<int>(ramp)) + " dph/s",
                       {GyroFault{g, 100.0, 0.0, 3600.0 * ramp}}});
    }
    const int g2 = g % 4 + 1;
    cases.push_back({"gyro " + std::to_string(g) + " ramp 10 then " + std::to_string(g2) + " step 100",
                     {GyroFault{g, 100.0, 0.0, 36000.0}, GyroFault{g2, 200.0, 100.0, 0.0}}});
  }
  // A step, then a ramp on another gyro once no parity is left (three gyros): the star rates must
  // follow the ramp as one fault. (After the cases above, which keep their seeds.) The star
  // innovations detect a 0.5-1 deg/h per s ramp only 8-20 s after its onset; the status is degraded
  // meanwhile because no spare gyro is left (policy.degraded_without_spare; docs/results.md).
  for (int g = 1; g <= 4; ++g) {
    const int g2 = g % 4 + 1;
    for (double ramp : {0.5, 1.0, 10.0}) {
      char name[80];
      std::snprintf(name, sizeof name, "gyro %d step 20 then %d ramp %g", g, g2, ramp);
      cases.push_back({name, {GyroFault{g, 100.0, 20.0, 0.0}, GyroFault{g2, 200.0, 0.0, 3600.0 * ramp}}});
    }
  }
  int fails = 0, below99 = 0;
  uint64_t seed = 1600;
  for (const Case& c : cases) {
    const Outcome o = RunCase(c, ++seed);
    EXPECT_GE(o.trust, c.min_trust) << c.name;
    EXPECT_TRUE(o.isolated_right) << c.name;
    fails += o.trust < c.min_trust || !o.isolated_right;
    below99 += o.trust < 0.99;
  }
  std::printf("%zu cases, %d below their bound or not isolated, %d below 99%%\n", cases.size(), fails, below99);
}

}  // namespace
}  // namespace ssiu
