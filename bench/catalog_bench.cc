// Catalog load (issue 17, fast start: <= 5 ms): LoadSolverCatalog of a built directory (read, size and
// CRC-32 check, parse) plus the StarIdentifier made from it, i.e. what `ssiu solve` does before its
// first frame; the BSC catalog for 16.6 deg built once into a temporary directory. With
// SSIU_BENCH_OLD_CATALOG=DIR (a directory written by an ssiu of catalog.bin format 3, before the index
// was stored) the same for that directory, whose features and index are rebuilt at every load.
//   build/bench/catalog_bench [--benchmark_repetitions=10]
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <string>

#include "core/catalog.h"
#include "identify/catalog_index.h"
#include "identify/identify.h"
#include "identify/star_catalog.h"

namespace ssiu {
namespace {

const std::string& BuiltDir() {
  static const std::string dir = [] {
    char tmpl[] = "/tmp/ssiu_catalog_bench_XXXXXX";
    const char* d = mkdtemp(tmpl);
    if (!d) std::abort();
    CatalogBuildOptions o;
    o.fov_deg = 16.6;
    SaveSolverCatalog(BuildSolverCatalog(LoadSourceCatalog(DefaultBscPath()), o), d);
    return std::string(d);
  }();
  return dir;
}

void LoadAndIdentifier(benchmark::State& state, const std::string& dir) {
  size_t triangles = 0;
  for (auto _ : state) {
    StarIdentifier id(LoadSolverCatalog(dir));
    triangles = id.catalog().triangles.size();
    benchmark::DoNotOptimize(triangles);
  }
  state.counters["triangles"] = static_cast<double>(triangles);
}

void BM_CatalogLoadStored(benchmark::State& state) { LoadAndIdentifier(state, BuiltDir()); }
BENCHMARK(BM_CatalogLoadStored)->Unit(benchmark::kMillisecond);

void BM_CatalogLoadFormat3(benchmark::State& state) {
  const char* old = std::getenv("SSIU_BENCH_OLD_CATALOG");
  if (!old || !*old) {
    state.SkipWithError("set SSIU_BENCH_OLD_CATALOG to a format-3 catalog directory");
    for (auto _ : state) {
    }
    return;
  }
  LoadAndIdentifier(state, old);
}
BENCHMARK(BM_CatalogLoadFormat3)->Unit(benchmark::kMillisecond);

// The part of the old load that storing the index removes: sorting the triangles' keys and building
// the stars' kd-tree.
void BM_CatalogIndexBuild(benchmark::State& state) {
  const SolverCatalog cat = LoadSolverCatalog(BuiltDir());
  for (auto _ : state) {
    CatalogIndex index(cat);
    benchmark::DoNotOptimize(index.Empty());
  }
}
BENCHMARK(BM_CatalogIndexBuild)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace ssiu

BENCHMARK_MAIN();
