// Fusion speed: one MEKF step (propagate + star update), one hour of 100 Hz four-FOG data, and the
// processor's estimator (OnlineFusion) over ten minutes of a slew about three axes with and without the
// in-flight unit calibration (argument 1: FuseOptions::calibrate_unit).
#include <benchmark/benchmark.h>

#include "inertial/fuse.h"
#include "inertial/mekf.h"
#include "inertial/online_fusion.h"
#include "inertial/propagate.h"
#include "sim/gyro_sim.h"

namespace ssiu {
namespace {

void BM_MekfPropagateAndUpdate(benchmark::State& state) {
  Mekf f;
  f.Init(Quat::Identity(), Vec3::Zero(), Mat6::Identity() * 1e-10);
  MekfNoise n;
  const Mat3 r = Mat3::Identity() * 1e-10;
  const Vec3 w(1e-3, -2e-3, 1.5e-3);
  const Quat q_meas = QuatFromRotationVector(Vec3(1e-6, 0, 0));
  for (auto _ : state) {
    f.Propagate(w, 0.01, n);
    benchmark::DoNotOptimize(f.UpdateAttitude(q_meas, r, 1e9));
  }
}
BENCHMARK(BM_MekfPropagateAndUpdate)->Unit(benchmark::kMicrosecond);

void BM_MekfPropagate(benchmark::State& state) {
  Mekf f;
  f.Init(Quat::Identity(), Vec3::Zero(), Mat6::Identity() * 1e-10);
  MekfNoise n;
  const Vec3 w(1e-3, -2e-3, 1.5e-3);
  for (auto _ : state) {
    f.Propagate(w, 0.01, n);
    benchmark::DoNotOptimize(f.q());
  }
}
BENCHMARK(BM_MekfPropagate)->Unit(benchmark::kMicrosecond);

void BM_FuseOneHour100Hz(benchmark::State& state) {
  GyroUnit unit = DefaultFourFogUnit();
  MotionProfile p;
  GyroSimOptions o;
  o.duration_s = 3600;
  const GyroSimulation sim = SimulateGyro(unit, p, o);
  GyroLog log;
  log.t_s = sim.t_s;
  log.rates_dph = sim.gyro_dph;
  StarTrackerLog st;
  st.t_s = sim.st_t_s;
  st.q_inertial_from_body = sim.st_q;
  FuseOptions fo;
  fo.output_every = 100;  // the fused output itself, not its storage, is what is timed
  for (auto _ : state) benchmark::DoNotOptimize(Fuse(log, st, unit, fo));
}
BENCHMARK(BM_FuseOneHour100Hz)->Unit(benchmark::kMillisecond)->Iterations(5);

void BM_OnlineFusionTenMinutes(benchmark::State& state) {
  const GyroUnit unit = DefaultFourFogUnit();
  MotionProfile p;
  p.type = "sine";
  p.amplitude_dps = Vec3(1, 1, 1);
  p.periods_s = Vec3(240, 330, 420);
  GyroSimOptions o;
  o.duration_s = 600;
  const GyroSimulation sim = SimulateGyro(unit, p, o);
  FuseOptions fo;
  fo.calibrate_unit = state.range(0) != 0;
  const double sc = 5 * kArcsecToRad, sr = 30 * kArcsecToRad;
  const Mat3 r = Vec3(sc * sc, sc * sc, sr * sr).asDiagonal();
  for (auto _ : state) {
    OnlineFusion f(unit, fo);
    size_t j = 0;
    for (size_t k = 0; k < sim.t_s.size(); ++k) {
      f.AddGyro(sim.t_s[k], sim.gyro_dph[k]);
      for (; j < sim.st_t_s.size() && sim.st_t_s[j] <= sim.t_s[k] + 1e-9; ++j)
        f.AddAttitude(sim.st_t_s[j], sim.st_q[j], r);
    }
    benchmark::DoNotOptimize(f.q());
  }
  state.counters["gyro_samples"] = static_cast<double>(sim.t_s.size());
  state.counters["us_per_gyro_sample"] =
      benchmark::Counter(static_cast<double>(sim.t_s.size()) * 1e-6,
                         benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_OnlineFusionTenMinutes)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace
}  // namespace ssiu

BENCHMARK_MAIN();
