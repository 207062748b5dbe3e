// Memory of the flight interface (flight/ssiu_flight.h) for 1, 2 and 3 heads of 512^2 and 1024^2
// (16.6 deg): the caller's block (ssiu_flight_memory_bytes: the handle and every workspace), the heap
// init still takes (counted by tests/testing/alloc_count.h's replaced allocation functions: bytes and
// allocations), the catalog's heap as loaded in place; the workspaces of a processor made on the heap,
// split into the detector's and identification's buffers (the processor's DetectBytes /
// IdentifyBytes) and the rest (the filter's); and the heap taken by a lost-in-space frame set of star
// frames after init (0 when the flight path keeps its rule). Reported as counters:
//   ./build/bench/flight_memory_bench --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <vector>

#include "core/output.h"
#include "flight/flight_config.h"
#include "flight/ssiu_flight.h"
#include "core/catalog.h"
#include "identify/star_catalog.h"
#include "sim/frame_sim.h"
#include "sim/mission.h"
#include "testing/alloc_count.h"

namespace ssiu {
namespace {

// The handle's memory, 16-byte aligned as ssiu_flight_init asks (std::max_align_t is 8 on 32-bit ARM).
struct alignas(16) Block16 {
  unsigned char bytes[16];
};

struct Blob {
  std::string bytes;
  uint32_t crc = 0;
};
const Blob& TheBlob() {
  static const Blob b = [] {
    Blob x;
    x.bytes = SolverCatalogBytes(MakeIdentifierForCamera("", MakeCamera(512, 512, 16.6), 0.0).catalog());
    x.crc = Crc32(x.bytes.data(), x.bytes.size());
    return x;
  }();
  return b;
}

void BM_FlightMemory(benchmark::State& state) {
  const int heads = static_cast<int>(state.range(0)), size = static_cast<int>(state.range(1));
  const Blob& blob = TheBlob();
  ssiu_flight_config c;
  ssiu_flight_default_config(&c);
  const Camera cam = MakeCamera(size, size, 16.6);
  c.n_heads = heads;
  for (int h = 0; h < heads; ++h) {
    c.heads[h] = c.heads[h % 2];
    c.heads[h].width_px = c.heads[h].height_px = size;
    c.heads[h].focal_length_px = cam.focal_length_px;
    c.heads[h].cx_px = c.heads[h].cy_px = cam.cx_px;
  }
  c.catalog_crc32 = blob.crc;
  testing::AllocationCounter n;
  const SolverCatalog cat = ParseSolverCatalog(blob.bytes.data(), blob.bytes.size(), "blob", /*star_tree=*/false,
                                               /*in_place=*/true);
  const long catalog_heap = n.Bytes();
  const size_t handle = ssiu_flight_memory_bytes(&c);
  std::vector<Block16> memory(handle / sizeof(Block16) + 1);
  long init_heap = 0, init_allocs = 0, frame_heap = 0, frame_allocs = 0;
  // The processor's per-frame buffers, as the handle makes them.
  const FlightSetup setup = FlightSetupFrom(c);
  const auto id = std::make_shared<const StarIdentifier>(cat);
  n.Reset();
  const UnitProcessor p(setup.heads, std::vector<std::shared_ptr<const StarIdentifier>>(heads, id), setup.unit,
                        setup.options);
  const long processor_heap = n.Bytes();
  // A star frame (the same for every head: lost in space on each).
  static const StarCatalog bsc = LoadXplanetBsc(DefaultBscPath());
  const Image16 stars = SimulateFrame(cam, bsc, Quat::Identity(), FrameSimOptions{}, 5).image;
  for (auto _ : state) {
    ssiu_flight* f = nullptr;
    n.Reset();
    if (ssiu_flight_init(&c, blob.bytes.data(), blob.bytes.size(), memory.data(),
                         memory.size() * sizeof(Block16), &f) != SSIU_OK) {
      state.SkipWithError("init failed");
      break;
    }
    init_heap = n.Bytes();
    init_allocs = n.Count();
    ssiu_frame fr[SSIU_FLIGHT_MAX_HEADS] = {};
    for (int h = 0; h < heads; ++h) fr[h] = ssiu_frame{stars.pixels.data(), size, size, 0};
    ssiu_frame_report r;
    n.Reset();
    ssiu_flight_frames(f, 0.0, fr, heads, &r);
    frame_heap = n.Bytes();
    frame_allocs = n.Count();
    ssiu_flight_shutdown(f);
  }
  state.counters["blob_bytes"] = static_cast<double>(blob.bytes.size());
  state.counters["memory_bytes"] = static_cast<double>(handle);
  state.counters["init_heap_bytes"] = static_cast<double>(init_heap);
  state.counters["init_heap_allocs"] = static_cast<double>(init_allocs);
  state.counters["catalog_heap_bytes"] = static_cast<double>(catalog_heap);
  state.counters["detect_heap_bytes"] = static_cast<double>(p.DetectBytes());
  state.counters["identify_heap_bytes"] = static_cast<double>(p.IdentifyBytes());
  // The rest of the processor: the filter (MEKF, parity monitor, star-rate samples, bias history).
  state.counters["filter_heap_bytes"] =
      static_cast<double>(processor_heap - static_cast<long>(p.DetectBytes() + p.IdentifyBytes()));
  state.counters["frame_heap_bytes"] = static_cast<double>(frame_heap);
  state.counters["frame_allocs"] = static_cast<double>(frame_allocs);
}
BENCHMARK(BM_FlightMemory)
    ->ArgsProduct({{1, 2, 3}, {512, 1024}})
    ->ArgNames({"heads", "size"})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ssiu

BENCHMARK_MAIN();
