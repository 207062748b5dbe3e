// Whole frame to quaternion: read a 1024x1024 16-bit frame, detect, identify, QUEST (simulated
// frames at random attitudes, 16.6 deg FOV). Argument 0: PNG (zlib inflate dominates the read);
// argument 1: FITS (uncompressed, as a frame grabber or the unit's processor would hand it over). Counters split the
// CPU time into the read (PNG decode) and the solve (detect + identify + QUEST), and give the detection alone with the
// solver's options, measured on the same frames after the timed loop.
//   taskset -c 1 build/bench/solve_bench --benchmark_filter=FrameToQuaternion
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "core/catalog.h"
#include "sim/frame_sim.h"

namespace ssiu {
namespace {

// CPU time of this thread (ms): the machine is shared, so wall time measures the neighbours too.
double CpuMs() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

void BM_FrameToQuaternion(benchmark::State& state) {
  const StarCatalog sky = LoadXplanetBsc(DefaultBscPath(), 7.0);
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  CatalogBuildOptions co;
  co.fov_deg = 16.6;
  const StarIdentifier id(BuildSolverCatalog(LoadSourceCatalog(DefaultBscPath()), co));
  std::vector<std::string> files;
  for (int i = 0; i < 20; ++i) {
    const bool fits = state.range(0) == 1;
    const std::string p = "/tmp/ssiu_solve_bench_" + std::to_string(i) + (fits ? ".fits" : ".png");
    FrameSimOptions fo;
    const Image16 image = SimulateFrame(cam, sky, RandomAttitude(900 + i), fo, 900 + i).image;
    if (fits) {
      WriteFits16(p, image);
    } else {
      WritePng16(p, image);
    }
    files.push_back(p);
  }
  SolveOptions so;
  so.detect.gain_e_per_adu = 0.5;
  std::vector<double> ms, read_ms, solve_ms;
  int solved = 0;
  size_t i = 0;
  for (auto _ : state) {
    const double t0 = CpuMs();
    const Frame fr = ReadFrame(files[i++ % files.size()]);
    const double t1 = CpuMs();
    const SolveResult r = SolveFrame(id, fr.image.view(), cam, so);
    const double t2 = CpuMs();
    ms.push_back(t2 - t0);
    read_ms.push_back(t1 - t0);
    solve_ms.push_back(t2 - t1);
    solved += r.status == SolveStatus::kSolved;
  }
  std::vector<double> detect_ms;
  DetectOptions dopt = so.detect;
  if (dopt.gain_e_per_adu == 0) dopt.gain_e_per_adu = cam.gain_e_per_adu;
  for (int rep = 0; rep < 3; ++rep) {
    for (const auto& f : files) {
      const Frame fr = ReadFrame(f);
      const double t0 = CpuMs();
      const Detections d = Detect(fr.image.view(), dopt);
      detect_ms.push_back(CpuMs() - t0);
      benchmark::DoNotOptimize(d.stars.size());
    }
  }
  for (const auto& f : files) std::remove(f.c_str());
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::sort(ms.begin(), ms.end());
  state.counters["median_cpu_ms"] = ms[ms.size() / 2];
  state.counters["p99_cpu_ms"] = ms[std::min(ms.size() - 1, ms.size() * 99 / 100)];
  state.counters["read_cpu_ms"] = median(read_ms);
  state.counters["solve_cpu_ms"] = median(solve_ms);
  state.counters["detect_cpu_ms"] = median(detect_ms);
  state.counters["solved_frac"] = static_cast<double>(solved) / ms.size();
}
BENCHMARK(BM_FrameToQuaternion)->ArgName("fits")->Arg(0)->Arg(1)->Iterations(100)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ssiu

BENCHMARK_MAIN();
