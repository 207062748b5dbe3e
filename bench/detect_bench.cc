// Detection time for a 1024x1024 16-bit simulated frame (simulator defaults), one core.
//   build/bench/detect_bench --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include "bench_frames.h"

namespace {

void BM_Detect1024(benchmark::State& state) {
  const ssiu::FrameSimOptions so;
  const ssiu::SimulatedFrame& f = ssiu::bench::Frame(static_cast<uint64_t>(state.range(0)));
  ssiu::bench::TimeDetect(state, f, ssiu::DetectOptionsForSimulation(ssiu::Camera{}, so, /*give_rate=*/false));
}
BENCHMARK(BM_Detect1024)->Arg(1)->Arg(2)->Arg(3)->Unit(benchmark::kMillisecond);

void BM_SimulateFrame1024(benchmark::State& state) { ssiu::bench::TimeSimulate(state, ssiu::FrameSimOptions{}); }
BENCHMARK(BM_SimulateFrame1024)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
