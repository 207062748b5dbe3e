// The unit's processor (inertial/unit_processor.h) on the frames of the built-in default mission
// (two 512x512 heads, 16.6 deg): one frame set in tracking (detect + match around the propagated
// attitude + multi-head QUEST + MEKF update), one lost in space, one gyro sample. Frames are
// rendered before timing.
#include <benchmark/benchmark.h>

#include <memory>

#include "sim/mission.h"

namespace ssiu {
namespace {

struct Setup {
  MissionConfig config = DefaultMissionConfig();
  MissionData data;
  std::vector<std::vector<SimulatedFrame>> frames;  // [frame][head]
  std::vector<std::shared_ptr<const StarIdentifier>> ids;
  static constexpr int kFrames = 20;

  Setup() {
    config.duration_s = kFrames;
    for (auto& h : config.heads) h.camera.gain_e_per_adu = config.frame_sim.gain_e_per_adu;
    data = SimulateMission(config);
    const StarCatalog cat = LoadXplanetBsc(DefaultBscPath());
    for (int i = 0; i < kFrames; ++i) {
      frames.emplace_back();
      for (int h = 0; h < static_cast<int>(config.heads.size()); ++h) {
        frames.back().push_back(SimulateMissionFrame(config, data, cat, i, h));
      }
    }
    const auto id = std::make_shared<const StarIdentifier>(MakeIdentifierForCamera("", config.heads[0].camera, 0.0));
    ids.assign(config.heads.size(), id);
  }
  std::vector<ImageView> Views(int i) const {
    std::vector<ImageView> v;
    for (const auto& f : frames[i]) v.push_back(f.image.view());
    return v;
  }
  // Feeds the gyro samples in (t_from, t_to].
  void Gyros(UnitProcessor* p, double t_from, double t_to) const {
    const auto& g = data.gyro;
    for (size_t k = 0; k < g.t_s.size(); ++k) {
      if (g.t_s[k] > t_from + 1e-9 && g.t_s[k] <= t_to + 1e-9) p->OnGyroSample(g.t_s[k], g.gyro_dph[k]);
    }
  }
};

const Setup& S() {
  static const Setup s;
  return s;
}

void BM_FrameSetTracking(benchmark::State& state) {
  const Setup& s = S();
  std::unique_ptr<UnitProcessor> p;
  int i = Setup::kFrames;
  for (auto _ : state) {
    if (i >= Setup::kFrames) {  // start again: first frame lost in space, untimed
      state.PauseTiming();
      p = std::make_unique<UnitProcessor>(s.config.heads, s.ids, s.config.unit, s.config.processor);
      p->OnFrames(s.data.frame_t_s[0], s.Views(0));
      i = 1;
      state.ResumeTiming();
    }
    state.PauseTiming();
    s.Gyros(p.get(), s.data.frame_t_s[i - 1], s.data.frame_t_s[i]);
    state.ResumeTiming();
    const FrameReport r = p->OnFrames(s.data.frame_t_s[i], s.Views(i));
    if (r.status != SolveStatus::kSolved) state.SkipWithError("frame set not solved");
    ++i;
  }
}
BENCHMARK(BM_FrameSetTracking)->Unit(benchmark::kMillisecond);

void BM_FrameSetLostInSpace(benchmark::State& state) {
  const Setup& s = S();
  int i = 0;
  for (auto _ : state) {
    state.PauseTiming();
    UnitProcessor p(s.config.heads, s.ids, s.config.unit, s.config.processor);
    state.ResumeTiming();
    const FrameReport r = p.OnFrames(s.data.frame_t_s[i], s.Views(i));
    if (r.status != SolveStatus::kSolved) state.SkipWithError("frame set not solved");
    i = (i + 1) % Setup::kFrames;
  }
}
BENCHMARK(BM_FrameSetLostInSpace)->Unit(benchmark::kMillisecond);

void BM_GyroSample(benchmark::State& state) {
  const Setup& s = S();
  UnitProcessor p(s.config.heads, s.ids, s.config.unit, s.config.processor);
  p.OnFrames(0.0, s.Views(0));
  const auto& g = s.data.gyro;
  size_t k = 0;
  double t_offset = 0;
  for (auto _ : state) {
    p.OnGyroSample(g.t_s[k] + t_offset, g.gyro_dph[k]);
    if (++k == g.t_s.size()) {
      k = 0;
      t_offset += g.t_s.back();
    }
  }
}
BENCHMARK(BM_GyroSample)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace ssiu

BENCHMARK_MAIN();
