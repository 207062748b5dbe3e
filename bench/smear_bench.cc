// Detection time while slewing: a 1024x1024 default frame turning at 0 / 1 / 2 deg/s about the sensor's
// X axis (0 / 6.2 / 12.3 px of smear), detected without and with the rate (DetectOptions::smear), and
// the simulator's time to render the smeared frame. One core.
//   BUILD/bench/smear_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include "bench_frames.h"

namespace {

// range(0): rate in 0.1 deg/s; range(1): 1 = the rate is handed to the detector.
void BM_DetectSmeared1024(benchmark::State& state) {
  const double rate_dps = 0.1 * static_cast<double>(state.range(0));
  const ssiu::SimulatedFrame& f = ssiu::bench::Frame(21, rate_dps);
  const ssiu::DetectOptions o =
      ssiu::DetectOptionsForSimulation(ssiu::Camera{}, ssiu::bench::SlewOptions(rate_dps), state.range(1) != 0);
  ssiu::bench::TimeDetect(state, f, o);
}
BENCHMARK(BM_DetectSmeared1024)
    ->Args({0, 0})
    ->Args({10, 0})
    ->Args({10, 1})
    ->Args({20, 0})
    ->Args({20, 1})
    ->Unit(benchmark::kMillisecond);

void BM_SimulateSmeared1024(benchmark::State& state) {
  ssiu::bench::TimeSimulate(state, ssiu::bench::SlewOptions(0.1 * static_cast<double>(state.range(0))));
}
BENCHMARK(BM_SimulateSmeared1024)->Arg(0)->Arg(10)->Arg(20)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
