// The unit's processor (inertial/unit_processor.h) on the frames of the built-in default mission
// (two 512x512 heads, 16.6 deg): one frame set in tracking (detect + match around the propagated
// attitude + multi-head QUEST + MEKF update), one lost in space, one gyro sample. Frames are
// rendered before timing.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <memory>

#include "core/output.h"
#include "flight/flight_config.h"
#include "flight/ssiu_flight.h"
#include "sim/mission.h"

namespace ssiu {
namespace {

// The handle's memory, 16-byte aligned as ssiu_flight_init asks (std::max_align_t is 8 on 32-bit ARM).
struct alignas(16) Block16 {
  unsigned char bytes[16];
};

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

// The same frame sets through the C interface (flight/ssiu_flight.h), as the flight core runs them:
// no diagnostics (no clock read, no text), nothing allocated after init.
struct FlightHandle {
  std::string blob;
  ssiu_flight_config config;
  std::vector<Block16> memory;
  ssiu_flight* f = nullptr;
  explicit FlightHandle(const Setup& s) {
    blob = SolverCatalogBytes(s.ids[0]->catalog());
    config = FlightConfigFor(s.config.heads, s.config.unit, s.config.processor, s.config.start_utc,
                             s.config.velocity_kms);
    config.catalog_crc32 = Crc32(blob.data(), blob.size());
    memory.resize(ssiu_flight_memory_bytes(&config) / sizeof(Block16) + 1);
  }
  bool Start() {
    if (f) ssiu_flight_shutdown(f);
    return ssiu_flight_init(&config, blob.data(), blob.size(), memory.data(), memory.size() * sizeof(Block16),
                            &f) == SSIU_OK;
  }
  ~FlightHandle() {
    if (f) ssiu_flight_shutdown(f);
  }
  bool Frames(const Setup& s, int i) {
    ssiu_frame fr[SSIU_FLIGHT_MAX_HEADS] = {};
    for (size_t h = 0; h < s.frames[i].size(); ++h) {
      const Image16& im = s.frames[i][h].image;
      fr[h] = ssiu_frame{im.pixels.data(), im.width, im.height, 0};
    }
    ssiu_frame_report r;
    return ssiu_flight_frames(f, s.data.frame_t_s[i], fr, config.n_heads, &r) == SSIU_OK &&
           r.status == SSIU_SOLVE_SOLVED;
  }
  void Gyros(const Setup& s, double t_from, double t_to) {
    const auto& g = s.data.gyro;
    for (size_t k = 0; k < g.t_s.size(); ++k) {
      if (g.t_s[k] > t_from + 1e-9 && g.t_s[k] <= t_to + 1e-9) {
        double out[SSIU_FLIGHT_MAX_GYROS];
        for (int j = 0; j < config.n_gyros; ++j) out[j] = g.gyro_dph[k][j];
        ssiu_flight_gyro(f, g.t_s[k], out, config.n_gyros, nullptr);
      }
    }
  }
};

void BM_FlightFrameSetTracking(benchmark::State& state) {
  const Setup& s = S();
  FlightHandle h(s);
  int i = Setup::kFrames;
  for (auto _ : state) {
    if (i >= Setup::kFrames) {  // start again: first frame lost in space, untimed
      state.PauseTiming();
      if (!h.Start() || !h.Frames(s, 0)) state.SkipWithError("init or first frame set failed");
      i = 1;
      state.ResumeTiming();
    }
    state.PauseTiming();
    h.Gyros(s, s.data.frame_t_s[i - 1], s.data.frame_t_s[i]);
    state.ResumeTiming();
    if (!h.Frames(s, i)) state.SkipWithError("frame set not solved");
    ++i;
  }
}
BENCHMARK(BM_FlightFrameSetTracking)->Unit(benchmark::kMillisecond);

void BM_FlightFrameSetLostInSpace(benchmark::State& state) {
  const Setup& s = S();
  FlightHandle h(s);
  int i = 0;
  for (auto _ : state) {
    state.PauseTiming();
    if (!h.Start()) state.SkipWithError("init failed");
    state.ResumeTiming();
    if (!h.Frames(s, i)) state.SkipWithError("frame set not solved");
    i = (i + 1) % Setup::kFrames;
  }
}
BENCHMARK(BM_FlightFrameSetLostInSpace)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ssiu

BENCHMARK_MAIN();
