// Catalog directories that cannot lie (issue 16): meta.json carries catalog.bin's size and CRC-32 and
// the field of view it was built for; a damaged catalog is detected (rebuilt in the cache, refused
// with the reason in a directory the user gave), one built for another FOV is refused, and a build
// killed before meta.json was written is finished by the next run.
#include <filesystem>
#include <fstream>
#include <functional>
#include <thread>
#include <vector>

#include "core/catalog.h"
#include "core/error.h"
#include "identify/star_catalog.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

using testing::ErrorOf;

CatalogBuildOptions Fov(double fov_deg) {
  CatalogBuildOptions o;
  o.fov_deg = fov_deg;
  return o;
}

TEST(CatalogIntegrity, TruncatedCatalogIsDetectedAndRebuiltOnlyInTheCache) {
  const std::string dir = testing::TempDir("catalog_integrity_trunc");
  const SolverCatalog built = LoadOrBuildCatalogIn(dir, DefaultBscPath(), Fov(20), false);
  ASSERT_EQ(CheckCatalogDir(dir), CatalogDirState::kOk);
  const auto bytes = std::filesystem::file_size(dir + "/catalog.bin");
  std::filesystem::resize_file(dir + "/catalog.bin", bytes / 2);  // a writer killed half-way, pre-issue
  std::string why;
  EXPECT_EQ(CheckCatalogDir(dir, &why), CatalogDirState::kDamaged);
  EXPECT_THAT(
      why, HasSubstr("damaged: " + std::to_string(bytes / 2) + " bytes, meta.json records " + std::to_string(bytes)));
  EXPECT_THAT(ErrorOf([&] { LoadSolverCatalog(dir); }), HasSubstr("damaged catalog"));
  // A directory the user gave: refused with the reason.
  EXPECT_THAT(ErrorOf([&] { LoadOrBuildCatalogIn(dir, DefaultBscPath(), Fov(20), false); }),
              HasSubstr("delete it or rebuild it"));
  // The same bytes flipped instead of cut: the CRC catches it.
  std::filesystem::resize_file(dir + "/catalog.bin", bytes);
  EXPECT_EQ(CheckCatalogDir(dir), CatalogDirState::kDamaged);
  // The cache: rebuilt, and then whole.
  const SolverCatalog again = LoadOrBuildCatalogIn(dir, DefaultBscPath(), Fov(20), true);
  EXPECT_EQ(again.triangles.size(), built.triangles.size());
  EXPECT_EQ(CheckCatalogDir(dir), CatalogDirState::kOk);
}

TEST(CatalogIntegrity, CatalogForAnotherFieldOfViewIsRefusedWithTheReason) {
  const std::string dir = testing::TempDir("catalog_integrity_fov");
  LoadOrBuildCatalogIn(dir, DefaultBscPath(), Fov(30), false);
  EXPECT_THAT(ErrorOf([&] { LoadOrBuildCatalogIn(dir, DefaultBscPath(), Fov(16.6), false); }),
              HasSubstr("catalog built for a 30.00 deg field of view, this camera needs 16.60 deg"));
  EXPECT_EQ(ErrorOf([&] { LoadOrBuildCatalogIn(dir, DefaultBscPath(), Fov(29), false); }), "no error");
}

TEST(CatalogIntegrity, BuildKilledBeforeMetaJsonIsFinishedByTheNextRun) {
  const std::string dir = testing::TempDir("catalog_integrity_killed");
  LoadOrBuildCatalogIn(dir, DefaultBscPath(), Fov(30), false);
  std::filesystem::remove(dir + "/meta.json");
  EXPECT_EQ(CheckCatalogDir(dir), CatalogDirState::kIncomplete);
  LoadOrBuildCatalogIn(dir, DefaultBscPath(), Fov(30), false);
  EXPECT_EQ(CheckCatalogDir(dir), CatalogDirState::kOk);
}

// Concurrent builders of one directory (issue 16, item 2): four at once on an empty directory all get
// the same whole catalog, and the directory is left whole with no temporary beside it.
TEST(CatalogIntegrity, ConcurrentBuildersOfOneDirectoryCannotTearIt) {
  const std::string dir = testing::TempDir("catalog_integrity_concurrent");
  const int n = 4;
  std::vector<SolverCatalog> cats(n);
  std::vector<std::string> errors(n);
  std::vector<std::thread> builders;
  for (int i = 0; i < n; ++i) {
    builders.emplace_back([&, i] {
      try {
        cats[i] = LoadOrBuildCatalogIn(dir, DefaultBscPath(), Fov(20), false);
      } catch (const std::exception& e) {
        errors[i] = e.what();
      }
    });
  }
  for (auto& t : builders) t.join();
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(errors[i], "") << "builder " << i;
    ASSERT_EQ(cats[i].stars.size(), cats[0].stars.size()) << "builder " << i;
    ASSERT_EQ(cats[i].triangles.size(), cats[0].triangles.size()) << "builder " << i;
    for (size_t k = 0; k < cats[i].stars.size(); k += 97) EXPECT_EQ(cats[i].stars[k].id, cats[0].stars[k].id);
  }
  EXPECT_GT(cats[0].triangles.size(), 1000u);
  EXPECT_EQ(CheckCatalogDir(dir), CatalogDirState::kOk);
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    // The atomic writer's temporaries are hidden files beside their targets (core/output.h).
    EXPECT_TRUE(name[0] != '.' || name == ".lock") << "left behind: " << name;
  }
}

}  // namespace
}  // namespace ssiu
