// Allan analysis speed: overlapping ADEV (10 points per decade) of 1 h of 100 Hz rate data, and the
// noise-term fit on the resulting curve.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "calibration/allan.h"
#include "core/rng.h"

namespace {

// White rate noise plus a rate random walk, in arbitrary units (speed does not depend on them).
std::vector<double> Rates(size_t n, double fs) {
  ssiu::Rng rng(1);
  std::vector<double> r(n);
  double b = 0;
  for (double& v : r) {
    b += 0.01 / std::sqrt(fs) * rng.Normal();
    v = std::sqrt(fs) * rng.Normal() + b;
  }
  return r;
}

void BM_OverlappingAdev1h100Hz(benchmark::State& state) {
  const double fs = 100;
  const std::vector<double> r = Rates(360000, fs);
  for (auto _ : state) {
    ssiu::AllanCurve c = ssiu::OverlappingAllanDeviation(r, fs);
    benchmark::DoNotOptimize(c.adev.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(r.size()));
}
BENCHMARK(BM_OverlappingAdev1h100Hz)->Unit(benchmark::kMillisecond);

void BM_FitNoiseTerms1h100Hz(benchmark::State& state) {
  const double fs = 100;
  const ssiu::AllanCurve c = ssiu::OverlappingAllanDeviation(Rates(360000, fs), fs);
  for (auto _ : state) {
    ssiu::NoiseFit f = ssiu::FitNoiseTerms(c);
    benchmark::DoNotOptimize(f.arw.value);
  }
}
BENCHMARK(BM_FitNoiseTerms1h100Hz)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
