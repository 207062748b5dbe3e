// Fusion speed: one MEKF step (propagate + star update) and one hour of 100 Hz four-FOG data.
#include <benchmark/benchmark.h>

#include "inertial/fuse.h"
#include "inertial/mekf.h"
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

}  // namespace
}  // namespace ssiu

BENCHMARK_MAIN();
