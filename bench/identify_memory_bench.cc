// Heap allocations and time of identification (docs/identify.md, "Memory"): the catalog star lookup
// about a field (the kd-tree's radius search, which allocates its answer and its search state, against
// the sky cells into caller storage), and lost in space and tracking by value against the workspace
// forms, on 50 synthetic 16.6-deg frames (BSC catalog, 0.2 px noise, 10% dropped, 3 false stars).
// Allocations counted by tests/testing/alloc_count.h's replaced allocation functions around each call.
// Time: per 1000 lookups (BM_StarsWithin), per 50 frames (BM_Identify). Counters per call:
//   ./build/bench/identify_memory_bench --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <vector>

#include "core/attitude.h"
#include "core/rng.h"
#include "identify/catalog_index.h"
#include "identify/identify.h"
#include "identify/synthetic.h"
#include "testing/alloc_count.h"

namespace ssiu {
namespace {

const Camera kCam = MakeCamera(1024, 1024, 16.6);

struct Frames {
  std::vector<std::vector<Centroid>> centroids;
  std::vector<Quat> truth;
  std::vector<Vec3> directions;  // random lookup centres
};
const Frames& F() {
  static const Frames f = [] {
    Frames x;
    const StarIdentifier& id = testing::Bsc166();
    for (int i = 0; i < 50; ++i) {
      Rng rng(1000 + i);
      const Quat q = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform());
      x.centroids.push_back(
          testing::MakeSyntheticFrame(id.catalog(), kCam, q, testing::SyntheticOptions{}, &rng).centroids);
      x.truth.push_back(q);
    }
    Rng rng(7);
    for (int i = 0; i < 1000; ++i)
      x.directions.push_back(QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform()).toRotationMatrix().col(2));
    return x;
  }();
  return f;
}

// The lookup of Verify and TestHypothesis: the circle of half the diagonal + 5% about the boresight.
double FieldRadius() { return kCam.FovDiagRad() / 2 * 1.05 + 0.002; }

// Allocations of the calls alone (not the benchmark's own), per call.
struct Allocs {
  testing::AllocationCounter n;
  long count = 0, bytes = 0, c0 = 0, b0 = 0;
  void Start() { c0 = n.Count(), b0 = n.Bytes(); }
  void Stop() { count += n.Count() - c0, bytes += n.Bytes() - b0; }
  void Report(benchmark::State& state, size_t calls) const {
    state.counters["allocs_per_call"] = static_cast<double>(count) / calls;
    state.counters["bytes_per_call"] = static_cast<double>(bytes) / calls;
  }
};

// range(0): 0 = the kd-tree's radius search, 1 = the sky cells into room for 800 stars.
void BM_StarsWithin(benchmark::State& state) {
  const CatalogIndex& index = *testing::Bsc166().catalog().index;
  const Frames& f = F();
  const bool cells = state.range(0) == 1;
  std::vector<int> buf(800);
  size_t calls = 0, stars = 0;
  Allocs a;
  for (auto _ : state) {
    for (const Vec3& u : f.directions) {
      a.Start();
      stars += cells ? index.StarsWithin(u, FieldRadius(), buf.data(), buf.size())
                     : index.StarsWithin(u, FieldRadius()).size();
      a.Stop();
      ++calls;
    }
  }
  a.Report(state, calls);
  state.counters["stars_per_call"] = static_cast<double>(stars) / calls;
  state.counters["sky_cell_bytes"] = static_cast<double>(index.SkyCellBytes());
  state.counters["catalog_stars"] = static_cast<double>(testing::Bsc166().catalog().stars.size());
}
BENCHMARK(BM_StarsWithin)->Arg(0)->Arg(1);

// range(0): 0 = by value, 1 = workspace (200 centroids x 800 stars, no diagnostics); range(1): 0 = lost
// in space, 1 = tracking from the truth turned by 0.1 deg.
void BM_Identify(benchmark::State& state) {
  const StarIdentifier& id = testing::Bsc166();
  const Frames& f = F();
  const bool workspace = state.range(0) == 1, tracking = state.range(1) == 1;
  IdentifyWorkspace ws(200, 800);
  Identification out;
  ws.Reserve(&out);
  const IdentifyOptions io;
  size_t calls = 0, solved = 0;
  Allocs a;
  for (auto _ : state) {
    for (size_t k = 0; k < f.centroids.size(); ++k) {
      const Quat q_pred = f.truth[k] * Quat(Eigen::AngleAxisd(0.1 * kDegToRad, Vec3(1, 1, 0).normalized()));
      SolveStatus s;
      a.Start();
      if (workspace && tracking) {
        s = id.MatchWithAttitude(f.centroids[k], kCam, q_pred, 30.0, io, &ws, &out);
      } else if (workspace) {
        s = id.Identify(f.centroids[k], kCam, io, &ws, &out);
      } else if (tracking) {
        s = id.MatchWithAttitude(f.centroids[k], kCam, q_pred, 30.0, io).status;
      } else {
        s = id.Identify(f.centroids[k], kCam, io).status;
      }
      a.Stop();
      solved += s == SolveStatus::kSolved;
      ++calls;
    }
  }
  a.Report(state, calls);
  state.SetItemsProcessed(static_cast<int64_t>(calls));  // items_per_second: calls per CPU second
  state.counters["solved_frac"] = static_cast<double>(solved) / calls;
  state.counters["workspace_bytes"] = static_cast<double>(ws.Bytes());
}
BENCHMARK(BM_Identify)->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ssiu

BENCHMARK_MAIN();
