// Detection time while slewing: a 1024x1024 default frame turning at 0 / 1 / 2 deg/s about the sensor's
// X axis (0 / 6.2 / 12.3 px of smear), detected without and with the rate (DetectOptions::smear), and
// the simulator's time to render the smeared frame. One core.
//   BUILD/bench/smear_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <map>

#include "core/catalog.h"
#include "detect/detect.h"
#include "sim/frame_sim.h"

namespace {

const ssiu::StarCatalog& Cat() {
  static const ssiu::StarCatalog cat = ssiu::LoadXplanetBsc(ssiu::DefaultBscPath());
  return cat;
}

ssiu::FrameSimOptions Options(double rate_dps) {
  ssiu::FrameSimOptions o;
  o.rate_x_dps = rate_dps;
  return o;
}

const ssiu::SimulatedFrame& Frame(int tenth_dps) {
  static std::map<int, ssiu::SimulatedFrame> frames;
  auto it = frames.find(tenth_dps);
  if (it == frames.end()) {
    const uint64_t seed = 21;
    it = frames.emplace(tenth_dps, ssiu::SimulateFrame(ssiu::Camera{}, Cat(), ssiu::RandomAttitude(seed),
                                                       Options(0.1 * tenth_dps), seed))
             .first;
  }
  return it->second;
}

// range(0): rate in 0.1 deg/s; range(1): 1 = the rate is handed to the detector.
void BM_DetectSmeared1024(benchmark::State& state) {
  const double rate_dps = 0.1 * static_cast<double>(state.range(0));
  const auto& f = Frame(static_cast<int>(state.range(0)));
  ssiu::DetectOptions o;
  o.gain_e_per_adu = ssiu::FrameSimOptions{}.gain_e_per_adu;
  if (state.range(1)) {
    o.smear.rate_rad_s = ssiu::Vec3(rate_dps * ssiu::kDegToRad, 0, 0);
    o.smear.exposure_s = ssiu::FrameSimOptions{}.exposure_s;
    o.smear.camera = ssiu::Camera{};
  }
  size_t stars = 0;
  for (auto _ : state) {
    const ssiu::Detections d = ssiu::Detect(f.image.view(), o);
    stars = d.stars.size();
    benchmark::DoNotOptimize(stars);
  }
  state.counters["stars"] = static_cast<double>(stars);
}
BENCHMARK(BM_DetectSmeared1024)
    ->Args({0, 0})
    ->Args({10, 0})
    ->Args({10, 1})
    ->Args({20, 0})
    ->Args({20, 1})
    ->Unit(benchmark::kMillisecond);

void BM_SimulateSmeared1024(benchmark::State& state) {
  const ssiu::FrameSimOptions o = Options(0.1 * static_cast<double>(state.range(0)));
  uint64_t seed = 1;
  for (auto _ : state) {
    auto f = ssiu::SimulateFrame(ssiu::Camera{}, Cat(), ssiu::RandomAttitude(seed), o, seed);
    benchmark::DoNotOptimize(f.image.pixels.data());
    ++seed;
  }
}
BENCHMARK(BM_SimulateSmeared1024)->Arg(0)->Arg(10)->Arg(20)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
