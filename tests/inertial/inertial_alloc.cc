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
#include <random>
#include <vector>

#include "core/attitude.h"
#include "core/catalog.h"
#include "inertial/analytic_fusion.h"
#include "inertial/online_fusion.h"
#include "inertial/unit_processor.h"
#include "sim/frame_sim.h"
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

// The in-flight unit calibration (FuseOptions::calibrate_unit) on the four-FOG unit turning about
// body x, y and z in turn, each way (100 s each, 0.5 deg/s, in closed form): every window closed, the estimate
// refreshed and applied in AddAttitude, with a NaN output every 997th sample
// breaking the open window, allocate nothing; and the estimate it reaches is the unit's true scale
// factor error (200 ppm on gyro 1) within 3 sigma.
TEST(InertialAlloc, UnitCalibrationAllocatesNothing) {
  GyroUnit unit = DefaultFourFogUnit();
  unit.rate_hz = 20;
  FuseOptions o;
  o.calibrate_unit = true;
  OnlineFusion f(unit, o);
  const GyroAxes h = unit.Axes();
  const double dt = 1.0 / unit.rate_hz, rate = 0.5 * kDegToRad, sf = 200e-6;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal;
  // +x, +y, +z, -x, -y, -z: rates of both signs keep the biases apart from the scale factors.
  auto rate_at = [&](double t) {
    const int seg = static_cast<int>(t / 100.0) % 6;
    return Vec3(Vec3::Unit(seg % 3) * (seg < 3 ? rate : -rate));
  };
  Quat q = QuatFromRotationVector(Vec3(0.4, 1.1, -0.7));
  const Mat3 r = Mat3::Identity() * std::pow(2 * kArcsecToRad, 2);
  AllocationCounter n;
  f.AddAttitude(0.0, q, r);
  for (long k = 1; k <= 12000; ++k) {
    const double t = k * dt;
    const Vec3 w = rate_at(t - 0.5 * dt);
    q = (q * QuatFromRotationVector(w * dt)).normalized();
    GyroVec g = h * w * kRadSToDph;
    g[0] *= 1 + sf;
    for (int i = 0; i < 4; ++i) g[i] += 0.5 + 0.01 * normal(rng);
    if (k % 997 == 0) g[k % 4] = std::numeric_limits<double>::quiet_NaN();
    f.AddGyro(t, g);
    if (k % static_cast<long>(unit.rate_hz) == 0) {
      const Vec3 e(normal(rng), normal(rng), normal(rng));
      f.AddAttitude(t, (q * QuatFromRotationVector(e * 2 * kArcsecToRad)).normalized(), r);
    }
  }
  EXPECT_EQ(n.Count(), 0);
  const UnitCalState& c = f.unit_calibration();
  std::printf(
      "unit calibration: %s, %d windows (%ld dropped), scale factors %.1f +- %.1f, %.1f +- %.1f ppm; %zu faults\n",
      UnitCalStatusName(c.status), c.n_windows, c.windows_dropped, c.scale_factor_ppm[0], c.scale_factor_sigma_ppm[0],
      c.scale_factor_ppm[1], c.scale_factor_sigma_ppm[1], f.faults().size());
  EXPECT_EQ(c.status, UnitCalStatus::kApplied);
  EXPECT_GT(c.n_windows, 20);
  EXPECT_GT(c.windows_dropped, 0);
  EXPECT_NEAR(c.scale_factor_ppm[0], 200, 3 * c.scale_factor_sigma_ppm[0]);
  EXPECT_NEAR(c.scale_factor_ppm[1], 0, 3 * c.scale_factor_sigma_ppm[1]);
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

// A head whose camera lists known hot pixels and a vignetting (camera.json's fields beyond the geometry):
// the map is built and the law kept at construction; a frame set then allocates nothing.
TEST(InertialAlloc, UnitProcessorHeadWithHotPixelsAndVignettingAllocatesNothingPerFrame) {
  OpticalHead head;
  head.camera = MakeCamera(512, 512, 16.6);
  head.extras.vignetting = 0.4;
  FrameSimOptions fo;
  fo.vignetting = head.extras.vignetting;
  const StarCatalog sky = LoadXplanetBsc(DefaultBscPath(), 7.0);
  std::vector<SimulatedFrame> frames;
  for (int k = 0; k < 3; ++k) frames.push_back(SimulateFrame(head.camera, sky, RandomAttitude(60), fo, 60 + k));
  for (const auto& a : frames[0].artefacts)
    if (a.type == "hot_pixel")
      head.extras.hot_pixels.push_back({static_cast<int>(std::lround(a.x_px)), static_cast<int>(std::lround(a.y_px))});
  ASSERT_FALSE(head.extras.hot_pixels.empty());
  UnitProcessorOptions o;
  o.diagnostics = false;
  o.solve.detect.gain_e_per_adu = fo.gain_e_per_adu;
  const auto id = std::make_shared<const StarIdentifier>(MakeIdentifierForCamera("", head.camera, 0.0));
  UnitProcessor p({head}, {id}, DefaultFourFogUnit(), o);
  FrameReport report;
  p.OnFrames(0.0, {frames[0].image.view()}, &report);  // sizes the report
  ASSERT_EQ(report.heads[0].status, SolveStatus::kSolved);
  const std::vector<std::vector<ImageView>> views = {{frames[1].image.view()}, {frames[2].image.view()}};
  AllocationCounter n;
  for (int k = 1; k < 3; ++k) {
    p.OnFrames(k * 1.0, views[k - 1], &report);
    EXPECT_EQ(report.heads[0].status, SolveStatus::kSolved) << k;
  }
  EXPECT_EQ(n.Count(), 0);
}

}  // namespace
}  // namespace ssiu
