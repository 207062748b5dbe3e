// Detection time for a 1024x1024 16-bit simulated frame (simulator defaults), one core.
//   build/bench/detect_bench --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <map>

#include "core/attitude.h"
#include "core/catalog.h"
#include "detect/detect.h"
#include "sim/frame_sim.h"

namespace {

const ssiu::SimulatedFrame& Frame(uint64_t seed) {
  static const ssiu::StarCatalog cat = ssiu::LoadXplanetBsc(ssiu::DefaultBscPath());
  static std::map<uint64_t, ssiu::SimulatedFrame> frames;
  auto it = frames.find(seed);
  if (it == frames.end()) {
    it = frames.emplace(seed, ssiu::SimulateFrame(ssiu::Camera{}, cat, ssiu::RandomAttitude(seed), ssiu::FrameSimOptions{}, seed)).first;
  }
  return it->second;
}

void BM_Detect1024(benchmark::State& state) {
  const auto& f = Frame(static_cast<uint64_t>(state.range(0)));
  ssiu::DetectOptions o;
  o.gain_e_per_adu = ssiu::FrameSimOptions{}.gain_e_per_adu;
  size_t stars = 0;
  for (auto _ : state) {
    const ssiu::Detections d = ssiu::Detect(f.image.view(), o);
    stars = d.stars.size();
    benchmark::DoNotOptimize(stars);
  }
  state.counters["stars"] = static_cast<double>(stars);
}
BENCHMARK(BM_Detect1024)->Arg(1)->Arg(2)->Arg(3)->Unit(benchmark::kMillisecond);

void BM_SimulateFrame1024(benchmark::State& state) {
  static const ssiu::StarCatalog cat = ssiu::LoadXplanetBsc(ssiu::DefaultBscPath());
  uint64_t seed = 1;
  for (auto _ : state) {
    auto f = ssiu::SimulateFrame(ssiu::Camera{}, cat, ssiu::RandomAttitude(seed), ssiu::FrameSimOptions{}, seed);
    benchmark::DoNotOptimize(f.image.pixels.data());
    ++seed;
  }
}
BENCHMARK(BM_SimulateFrame1024)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
