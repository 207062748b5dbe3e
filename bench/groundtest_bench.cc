// Ground-test speed: mask design, one virtual-stand tracker frame and aux photo, the AprilTag + PnP
// plate pose of a photo, and the comparison of 1000 pictures.
#include <benchmark/benchmark.h>

#include <memory>

#include "core/attitude.h"
#include "groundtest/compare.h"
#include "groundtest/mask.h"
#include "groundtest/reference.h"
#include "groundtest/virtual_stand.h"
#include "identify/star_catalog.h"
#include "sim/frame_sim.h"

namespace {

const ssiu::Mask& OrionMask() {
  static const ssiu::Mask m = [] {
    ssiu::CatalogBuildOptions co;
    co.fov_deg = 16.6;
    const ssiu::SolverCatalog cat = ssiu::BuildSolverCatalog(ssiu::LoadXplanetBsc(ssiu::DefaultBscPath(), 7.0), co);
    return ssiu::DesignMask(ssiu::MakeCamera(1024, 1024, 16.6), cat.stars,
                            ssiu::QuatFromRaDecRoll(83.8 * ssiu::kDegToRad, -1 * ssiu::kDegToRad, 20 * ssiu::kDegToRad),
                            ssiu::MaskOptions{});
  }();
  return m;
}

void BM_TrackerView1024(benchmark::State& state) {
  const ssiu::Mask& m = OrionMask();
  uint64_t seed = 1;
  for (auto _ : state) {
    ssiu::Image16 img =
        ssiu::RenderTrackerView(m, ssiu::PlatePose{}, ssiu::Quat::Identity(), ssiu::TrackerViewOptions{}, seed++);
    benchmark::DoNotOptimize(img.pixels.data());
  }
}
BENCHMARK(BM_TrackerView1024)->Unit(benchmark::kMillisecond);

void BM_AuxPhoto1280x960(benchmark::State& state) {
  const ssiu::Mask& m = OrionMask();
  uint64_t seed = 1;
  for (auto _ : state) {
    auto p = ssiu::RenderAuxPhoto(m, ssiu::PlatePose{}, ssiu::AuxCamera{}, ssiu::PhotoOptions{}, seed++);
    benchmark::DoNotOptimize(p.data());
  }
}
BENCHMARK(BM_AuxPhoto1280x960)->Unit(benchmark::kMillisecond);

void BM_PlatePoseFromPhoto(benchmark::State& state) {
  const ssiu::Mask& m = OrionMask();
  const ssiu::AuxCamera aux;
  const auto p = ssiu::RenderAuxPhoto(m, ssiu::PlatePose{}, aux, ssiu::PhotoOptions{}, 1);
  for (auto _ : state) {
    auto e = ssiu::EstimatePlatePose(m, aux, p.data(), aux.camera.width, aux.camera.height, "photo");
    benchmark::DoNotOptimize(e.q_c_from_m);
  }
}
BENCHMARK(BM_PlatePoseFromPhoto)->Unit(benchmark::kMillisecond);

void BM_Compare1000(benchmark::State& state) {
  std::vector<ssiu::AttitudeSample> ref, est;
  for (int i = 0; i < 1000; ++i) {
    ssiu::AttitudeSample a;
    a.t_s = i, a.q = ssiu::RandomAttitude(i), a.sigma_cross_rad = 1e-5, a.sigma_roll_rad = 1e-4;
    ref.push_back(a);
    a.q = a.q * ssiu::Quat(1, 1e-5, -1e-5, 2e-5).normalized();
    est.push_back(a);
  }
  for (auto _ : state) {
    auto c = ssiu::CompareAttitudes(ref, est, ssiu::CompareOptions{});
    benchmark::DoNotOptimize(c.misalignment_rad);
  }
}
BENCHMARK(BM_Compare1000)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
