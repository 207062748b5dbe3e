// Speed of the FOG bench calibration on the simulated campaign: the thermal fit (two 700-minute
// 1 Hz runs, all 1024 subsets) and the turntable fit (25 positions).
#include <benchmark/benchmark.h>

#include "calibration/fog_magnetic.h"
#include "calibration/fog_thermal.h"
#include "sim/fog_bench_sim.h"

namespace {

std::vector<ssiu::ThermalRun> CampaignRuns() {
  std::vector<ssiu::ThermalRun> runs;
  ssiu::ThermalBenchOptions o;
  o.drift = ssiu::CampaignDriftModel();
  for (uint64_t seed : {1, 2}) {
    o.seed = seed;
    const ssiu::ThermalBenchRun s = ssiu::SimulateThermalRun(o);
    runs.push_back({"run", s.t_s, s.w_dph, s.ref_dph, s.temp_c});
  }
  return runs;
}

void BM_FitThermalDrift(benchmark::State& state) {
  const auto runs = CampaignRuns();
  for (auto _ : state) benchmark::DoNotOptimize(ssiu::FitThermalDrift(runs, ssiu::ThermalFitOptions{}));
}
BENCHMARK(BM_FitThermalDrift)->Unit(benchmark::kMillisecond);

void BM_CompensateThermalRun(benchmark::State& state) {
  const auto runs = CampaignRuns();
  for (auto _ : state) {
    benchmark::DoNotOptimize(ssiu::CompensateThermalRun(runs[0], ssiu::CampaignDriftModel(), {}));
  }
}
BENCHMARK(BM_CompensateThermalRun)->Unit(benchmark::kMillisecond);

void BM_FitMagneticSensitivity(benchmark::State& state) {
  const ssiu::TurntableLog log = ssiu::SimulateTurntable(ssiu::TurntableOptions{});
  const ssiu::TurntableData d{"log", log.t_s, log.wx_dph, log.wy_dph, log.azimuth_deg};
  for (auto _ : state) benchmark::DoNotOptimize(ssiu::FitMagneticSensitivity(d, ssiu::MagneticOptions{}));
}
BENCHMARK(BM_FitMagneticSensitivity)->Unit(benchmark::kMillisecond);

}  // namespace
BENCHMARK_MAIN();
