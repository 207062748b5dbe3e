// Frames shared by the detection benchmarks (detect_bench, smear_bench): default-camera 1024x1024
// frames simulated once per (seed, rate about the sensor's X axis) and kept, and the timed loops.
// Not a benchmark program itself (bench/CMakeLists.txt builds only *_bench.cc).
#pragma once

#include <benchmark/benchmark.h>

#include <map>
#include <utility>

#include "core/catalog.h"
#include "detect/detect.h"
#include "sim/detection_score.h"
#include "sim/frame_sim.h"

namespace ssiu::bench {

inline const StarCatalog& Bsc() {
  static const StarCatalog cat = LoadXplanetBsc(DefaultBscPath());
  return cat;
}

// Simulator defaults, turning at rate_x_dps about the sensor's X axis during the exposure.
inline FrameSimOptions SlewOptions(double rate_x_dps) {
  FrameSimOptions o;
  o.rate_x_dps = rate_x_dps;
  return o;
}

inline const SimulatedFrame& Frame(uint64_t seed, double rate_x_dps = 0.0) {
  static std::map<std::pair<uint64_t, double>, SimulatedFrame> frames;
  const auto key = std::make_pair(seed, rate_x_dps);
  auto it = frames.find(key);
  if (it == frames.end()) {
    it = frames.emplace(key, SimulateFrame(Camera{}, Bsc(), RandomAttitude(seed), SlewOptions(rate_x_dps), seed)).first;
  }
  return it->second;
}

// Times Detect on `frame`; the counter "stars" is the number reported.
inline void TimeDetect(benchmark::State& state, const SimulatedFrame& frame, const DetectOptions& options) {
  size_t stars = 0;
  for (auto _ : state) {
    const Detections d = Detect(frame.image.view(), options);
    stars = d.stars.size();
    benchmark::DoNotOptimize(stars);
  }
  state.counters["stars"] = static_cast<double>(stars);
}

// Times rendering a new frame (a new attitude and seed each iteration).
inline void TimeSimulate(benchmark::State& state, const FrameSimOptions& options) {
  uint64_t seed = 1;
  for (auto _ : state) {
    auto f = SimulateFrame(Camera{}, Bsc(), RandomAttitude(seed), options, seed);
    benchmark::DoNotOptimize(f.image.pixels.data());
    ++seed;
  }
}

}  // namespace ssiu::bench
