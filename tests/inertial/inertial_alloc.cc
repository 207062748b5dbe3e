// No heap allocation on the estimator's per-sample path after construction (issue 26; online_fusion.h
// "Flight rules"): the four-FOG unit and a six-gyro unit on a closed-form slew with a 1 Hz star
// tracker (analytic_fusion.h), through parity warm-up, fault detection, isolation (from the star rates
// with four gyros, from the parity with six, inside AddGyro), a second fault compensated on the last
// three gyros, and bad samples. Every allocation inside AddGyro and AddAttitude is counted from the
// first call on: no warm-up is excluded. A program of its own: the counting operator new
// (testing/alloc_count.h) must not slow the other tests.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "inertial/analytic_fusion.h"
#include "inertial/online_fusion.h"
#include "inertial/unit_processor.h"
#include "testing/alloc_count.h"

namespace ssiu {
namespace {

using testing::AllocationCounter;
using testing::AnalyticFusion;

struct Counts {
  long gyro = 0, attitude = 0;
};

// Runs t in (0, duration_s] at the unit's rate with a fix every second; `second_fault` adds a step on
// a second gyro from its time on; every 997th sample gets a NaN in one output.
Counts RunCounted(AnalyticFusion* sim, OnlineFusion* f, double duration_s, int second_gyro = -1,
                  double second_t_s = 0, double second_dph = 0) {
  Counts c;
  AllocationCounter n;
  Mat3 r;
  const Quat q0 = sim->Star(0.0, &r);
  long before = n.Count();
  f->AddAttitude(0.0, q0, r);
  c.attitude += n.Count() - before;
  const long steps = std::lround(duration_s * sim->unit.rate_hz);
  for (long k = 1; k <= steps; ++k) {
    const double t = k * sim->dt_s;
    GyroVec g = sim->Gyro(t);
    if (second_gyro >= 0 && t > second_t_s) g[second_gyro] += second_dph;
    if (k % 997 == 0) g[k % g.size()] = std::numeric_limits<double>::quiet_NaN();
    before = n.Count();
    f->AddGyro(t, g);
    c.gyro += n.Count() - before;
    if (k % std::lround(sim->unit.rate_hz) == 0) {
      const Quat q = sim->Star(t, &r);
      before = n.Count();
      f->AddAttitude(t, q, r);
      c.attitude += n.Count() - before;
    }
  }
  return c;
}

// Four FOGs: a 20 deg/h step on gyro 2 at 100 s is detected by the parity, isolated from the star
// rates (in AddAttitude), and the monitor restarts on the other three (one parity relation fewer:
// none left, so the star innovations watch from then on); a 30 deg/h step on gyro 3 at 200 s is then
// found by the innovation test and compensated (no spare), its fit refitted at every fix.
// The counter counts (a test that passes because nothing is counted proves nothing).
TEST(InertialAlloc, CounterCounts) {
  AllocationCounter n;
  std::vector<int>* volatile v = new std::vector<int>(100);
  delete v;
  EXPECT_GE(n.Count(), 2);
}

TEST(InertialAlloc, FourFogFaultsAllocateNothing) {
  AnalyticFusion sim(4);
  sim.SetFault(1, 100, 20);
  OnlineFusion f(sim.unit, FuseOptions{});
  const Counts c = RunCounted(&sim, &f, 400, 2, 200, 30);
  EXPECT_EQ(c.gyro, 0);
  EXPECT_EQ(c.attitude, 0);
  ASSERT_GE(f.faults().size(), 2u);
  EXPECT_EQ(f.faults()[0].gyro, 2);
  EXPECT_EQ(f.faults()[0].status, FaultStatus::kIsolated);
  EXPECT_EQ(f.faults()[0].method, "star_rates");
  EXPECT_EQ(f.faults()[1].gyro, 3);
  EXPECT_EQ(f.faults()[1].status, FaultStatus::kIsolated);
  EXPECT_EQ(f.n_gyros_in_use(), 3);
  EXPECT_GT(f.n_gyro_status(GyroSampleStatus::kAcceptedPartial), 0);
  std::printf("four FOGs: %zu fault events, gyro %d at %.1f s (%s), gyro %d at %.1f s; %ld partial samples\n",
              f.faults().size(), f.faults()[0].gyro, f.faults()[0].t_isolate_s, f.faults()[0].method.c_str(),
              f.faults()[1].gyro, f.faults()[1].t_isolate_s, f.n_gyro_status(GyroSampleStatus::kAcceptedPartial));
}

// Six gyros: a 200 deg/h step on gyro 5 is isolated by the parity direction inside AddGyro (the rate
// solution, the noise model and the parity monitor rebuilt there).
TEST(InertialAlloc, SixGyroParityIsolationAllocatesNothing) {
  AnalyticFusion sim(6);
  sim.SetFault(4, 60, 200);
  OnlineFusion f(sim.unit, FuseOptions{});
  const Counts c = RunCounted(&sim, &f, 150);
  EXPECT_EQ(c.gyro, 0);
  EXPECT_EQ(c.attitude, 0);
  ASSERT_EQ(f.faults().size(), 1u);
  EXPECT_EQ(f.faults()[0].gyro, 5);
  EXPECT_EQ(f.faults()[0].method, "parity");
  EXPECT_EQ(f.n_gyros_in_use(), 5);
}

// The unit processor's gyro call, and the frame calls that refuse or have nothing to solve (no view,
// a view of the wrong size, a wrong number of views) into a caller-owned report, with diagnostics off.
TEST(InertialAlloc, UnitProcessorGyroSamplesAndRefusedFramesAllocateNothing) {
  UnitProcessorOptions o;
  o.diagnostics = false;
  AnalyticFusion sim(4);
  const auto processor = testing::TwoHeadProcessor(sim.unit, o);
  UnitProcessor& p = *processor;
  const Image16 small(64, 64, 100);
  const std::vector<ImageView> none = {ImageView{}, ImageView{}}, wrong = {small.view(), ImageView{}},
                               one = {ImageView{}};
  FrameReport report;
  UnitAttitude att;
  p.OnFrames(0.0, none, &report);  // sizes the report
  p.Attitude(&att);
  AllocationCounter n;
  for (long k = 1; k <= 6000; ++k) {
    const double t = k * sim.dt_s;
    GyroVec g = sim.Gyro(t);
    if (k % 997 == 0) g[1] = std::numeric_limits<double>::quiet_NaN();
    p.OnGyroSample(t, g);
    p.OnGyroSample(t - 0.5, g);  // out of order
    if (k % 100 == 0) {
      p.OnFrames(t, k % 300 == 0 ? wrong : k % 200 == 0 ? one : none, &report);
      p.Attitude(&att);
    }
  }
  EXPECT_EQ(n.Count(), 0);
  EXPECT_EQ(att.gyro_samples_refused, 6000);
  EXPECT_EQ(att.gyro_samples_partial, 6);
  EXPECT_EQ(att.frames_refused, 40);  // 20 of the wrong size, 20 with one view for two heads
}

}  // namespace
}  // namespace ssiu
