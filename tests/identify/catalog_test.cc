#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <vector>

#include "core/astrometry.h"
#include "core/attitude.h"
#include "core/error.h"
#include "identify/star_catalog.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

const CatalogStar* FindId(StarSpan v, StarId id) {
  for (const auto& s : v)
    if (s.id == id) return &s;
  return nullptr;
}

TEST(Catalog, Bsc5BinaryAgreesWithXplanetBsc) {
  SSIU_REQUIRE_SHARED(path, "catalog/bsc5");
  const SourceCatalog b5 = LoadBsc5(path);
  EXPECT_GT(b5.stars.size(), 9000u);
  const StarCatalog xp = LoadXplanetBsc(DefaultBscPath());
  // Arcturus, HR 5340: same J2000 position in both (xplanet rounds RA to 1e-4 h = 5.4 arcsec),
  // and its large proper motion (-1.093, -1.999 arcsec/yr; mu_alpha* convention).
  const SourceStar* arc = nullptr;
  for (const auto& s : b5.stars)
    if (s.star.id == 5340) arc = &s;
  ASSERT_NE(arc, nullptr);
  const CatalogStar* x = FindId(xp.stars, 5340);
  ASSERT_NE(x, nullptr);
  EXPECT_LT(std::acos(std::min(1.0, arc->star.unit.dot(x->unit))) * kRadToArcsec, 6.0);
  EXPECT_NEAR(arc->pm_ra_rad_per_yr * kRadToArcsec, -1.093, 0.01);
  EXPECT_NEAR(arc->pm_dec_rad_per_yr * kRadToArcsec, -1.999, 0.01);
  EXPECT_NEAR(arc->star.mag, -0.04, 0.02);
}

TEST(Catalog, KstarsReaderAndProperMotion) {
  const std::string path = "/usr/share/kstars/stars.dat";
  if (!std::ifstream(path)) GTEST_SKIP() << path << " not installed (apt-get install kstars-data)";
  SourceCatalog k = LoadKstarsStars(path);
  EXPECT_GT(k.stars.size(), 120000u);
  // First data row is Sirius: RA 06 45 08.92, Dec -16 42 58.0, pm -546.0, -1223.1 mas/yr, V -1.44.
  const SourceStar& s = k.stars[0];
  EXPECT_EQ(s.star.id, kKstarsIdOffset + 1);
  EXPECT_NEAR(s.star.ra_rad * kRadToDeg, (6 + 45 / 60.0 + 8.92 / 3600) * 15, 1e-6);
  EXPECT_NEAR(s.star.dec_rad * kRadToDeg, -(16 + 42 / 60.0 + 58.0 / 3600), 1e-6);
  EXPECT_NEAR(s.pm_dec_rad_per_yr * kRadToArcsec, -1.2231, 1e-6);
  EXPECT_DOUBLE_EQ(s.star.mag, -1.44);
  // Cross-identification gives Sirius its HR number (2491).
  AssignHrNumbers(&k, LoadXplanetBsc(DefaultBscPath()));
  EXPECT_EQ(k.stars[0].star.id, 2491);
  // Proper motion over 25 years moves Sirius by |pm| * 25 = 33.5 arcsec.
  CatalogBuildOptions o;
  o.fov_deg = 20;
  o.mag_max = 2.0;
  o.epoch_year = 2025.0;
  const SolverCatalog c = BuildSolverCatalog(k, o);
  const CatalogStar* sirius = FindId(c.stars, 2491);
  ASSERT_NE(sirius, nullptr);
  const double moved = std::acos(std::min(1.0, sirius->unit.dot(s.star.unit))) * kRadToArcsec;
  EXPECT_NEAR(moved, 25 * std::hypot(0.546, 1.2231), 0.05);
  // The solver catalog keeps the proper motion (catalog.bin v3), so a solve brings Sirius on to the
  // frame's date: 10 more years from the 2025.0 catalog, as from J2000 directly.
  const std::string dir = testing::TempDir("catalog_pm");
  SaveSolverCatalog(c, dir);
  const SolverCatalog back = LoadSolverCatalog(dir);
  const CatalogStar* b = FindId(back.stars, 2491);
  ASSERT_NE(b, nullptr);
  EXPECT_NEAR(b->pm_dec_rad_per_yr * kRadToArcsec, -1.2231, 1e-6);
  EXPECT_NEAR(b->pm_ra_rad_per_yr * kRadToArcsec, -0.546, 1e-6);
  const Vec3 at_2035 = PropagateProperMotion(*b, back.epoch_year, 2035.0);
  const CatalogStar* j2000 = &s.star;
  CatalogStar with_pm = *j2000;
  with_pm.pm_ra_rad_per_yr = s.pm_ra_rad_per_yr;
  with_pm.pm_dec_rad_per_yr = s.pm_dec_rad_per_yr;
  EXPECT_LT(std::acos(std::min(1.0, at_2035.dot(PropagateProperMotion(with_pm, 2000.0, 2035.0)))) * kRadToArcsec, 0.01);
}

TEST(Catalog, CloseDoublesAreMergedByFlux) {
  StarCatalog sc;
  sc.source = "synthetic";
  auto add = [&](StarId id, double ra_deg, double dec_deg, double mag) {
    CatalogStar s;
    s.id = id, s.ra_rad = ra_deg * kDegToRad, s.dec_rad = dec_deg * kDegToRad, s.mag = mag;
    s.unit = UnitFromRaDec(s.ra_rad, s.dec_rad);
    sc.stars.push_back(s);
  };
  add(1, 10.0, 0.0, 3.0);
  add(2, 10.0 + 20.0 / 3600, 0.0, 3.0);  // 20 arcsec away, equal brightness: merged to the midpoint
  add(3, 12.0, 0.0, 4.0);                // far away: kept
  CatalogBuildOptions o;
  o.fov_deg = 10;
  o.mag_max = 6;
  o.double_star_arcsec = 60;
  const SolverCatalog c = BuildSolverCatalog(sc, o);
  ASSERT_EQ(c.stars.size(), 2u);
  EXPECT_EQ(c.stars[0].id, 1);
  EXPECT_NEAR(c.stars[0].mag, 3.0 - 2.5 * std::log10(2.0), 1e-9);
  EXPECT_NEAR(c.stars[0].ra_rad * kRadToDeg, 10.0 + 10.0 / 3600, 1e-6);
}

TEST(Catalog, BuildSaveLoadRoundTripAndIndexCoversTheSky) {
  CatalogBuildOptions o;
  o.fov_deg = 16.6;
  const SolverCatalog c = BuildSolverCatalog(LoadSourceCatalog(DefaultBscPath()), o);
  EXPECT_GT(c.mag_max, 5.5);
  EXPECT_LT(c.mag_max, 7.0);
  EXPECT_GT(c.triangles.size(), 10000u);
  // Every triangle fits in the FOV and its features are consistent with its stars.
  for (size_t i = 0; i < c.triangles.size(); i += 997) {
    const auto& t = c.triangles[i];
    const double l = std::acos(std::min(1.0, c.stars[t.v[0]].unit.dot(c.stars[t.v[1]].unit)));
    EXPECT_NEAR(l, t.longest_rad, 1e-6);
    EXPECT_LE(t.longest_rad, 16.6 * kDegToRad + 1e-6);
    EXPECT_LE(t.ratio_a, t.ratio_b);
  }
  const std::string dir = testing::TempDir("catalog_roundtrip");
  SaveSolverCatalog(c, dir);
  const SolverCatalog back = LoadSolverCatalog(dir);
  ASSERT_EQ(back.stars.size(), c.stars.size());
  ASSERT_EQ(back.triangles.size(), c.triangles.size());
  EXPECT_EQ(back.stars[100].id, c.stars[100].id);
  EXPECT_EQ(back.triangles.back().v, c.triangles.back().v);
  EXPECT_DOUBLE_EQ(back.mag_max, c.mag_max);
  // A corrupt file is an InputError naming it.
  { std::ofstream(dir + "/catalog.bin") << "garbage"; }
  EXPECT_THROW(LoadSolverCatalog(dir), InputError);
}

// The K-nearest-neighbour index is a subset of the full one (every triangle that fits in the FOV),
// several times smaller, and its features survive the save/load.
TEST(Catalog, NeighbourLimitedIndexIsASmallerSubset) {
  const SourceCatalog src = LoadSourceCatalog(DefaultBscPath());
  CatalogBuildOptions o;
  o.fov_deg = 16.6;
  o.pattern_neighbours = 0;
  const SolverCatalog all = BuildSolverCatalog(src, o);
  o.pattern_neighbours = 10;
  o.pattern_bright_neighbours = 0;
  const SolverCatalog k10 = BuildSolverCatalog(src, o);
  ASSERT_EQ(all.stars.size(), k10.stars.size());
  EXPECT_LT(k10.triangles.size() * 4, all.triangles.size());
  // Each pattern star of N holds at most K(K-1)/2 triangles with two of its neighbours.
  EXPECT_LE(k10.triangles.size(), static_cast<size_t>(k10.num_pattern_stars) * 45);
  EXPECT_GT(k10.triangles.size(), static_cast<size_t>(k10.num_pattern_stars) * 10);
  // Vertex triples as sorted 64-bit keys (star indices < 2^21).
  auto keys = [](const SolverCatalog& c) {
    std::vector<uint64_t> k;
    k.reserve(c.triangles.size());
    for (const auto& t : c.triangles) {
      std::array<int32_t, 3> v = t.v;
      std::sort(v.begin(), v.end());
      k.push_back(static_cast<uint64_t>(v[0]) << 42 | static_cast<uint64_t>(v[1]) << 21 | static_cast<uint64_t>(v[2]));
    }
    std::sort(k.begin(), k.end());
    return k;
  };
  const std::vector<uint64_t> full = keys(all), sub = keys(k10);
  EXPECT_TRUE(std::adjacent_find(sub.begin(), sub.end()) == sub.end()) << "duplicate triangle";
  EXPECT_TRUE(std::includes(full.begin(), full.end(), sub.begin(), sub.end())) << "a triangle not in the full index";
  // With the 5 brightest beyond the 10 nearest: (K + B)(K + B - 1) / 2 = 105 at most per pattern
  // star, between the two, holding every triangle of the 10 nearest.
  o.pattern_bright_neighbours = 5;
  const SolverCatalog k10b5 = BuildSolverCatalog(src, o);
  const std::vector<uint64_t> sub_b = keys(k10b5);
  EXPECT_LE(k10b5.triangles.size(), static_cast<size_t>(k10b5.num_pattern_stars) * 105);
  EXPECT_GT(k10b5.triangles.size(), k10.triangles.size());
  EXPECT_LT(k10b5.triangles.size(), all.triangles.size());
  EXPECT_TRUE(std::includes(full.begin(), full.end(), sub_b.begin(), sub_b.end()));
  EXPECT_TRUE(std::includes(sub_b.begin(), sub_b.end(), sub.begin(), sub.end()));
  const std::string dir = testing::TempDir("catalog_k10");
  SaveSolverCatalog(k10, dir);
  const SolverCatalog back = LoadSolverCatalog(dir);
  EXPECT_EQ(back.pattern_neighbours, 10);
  ASSERT_EQ(back.triangles.size(), k10.triangles.size());
  for (size_t i = 0; i < k10.triangles.size(); i += 101) {
    EXPECT_EQ(back.triangles[i].v, k10.triangles[i].v);
    EXPECT_NEAR(back.triangles[i].longest_rad, k10.triangles[i].longest_rad, 1e-6);
    EXPECT_NEAR(back.triangles[i].ratio_a, k10.triangles[i].ratio_a, 1e-6);
    EXPECT_NEAR(back.triangles[i].ratio_b, k10.triangles[i].ratio_b, 1e-6);
  }
  // On disk, stored as searched (nothing computed at load): 36 bytes per triangle (vertices, features,
  // key, place in key order) plus 100 per star (id, ra, dec, mag, unit vector, proper motion, place in
  // the sky cells and its unit vector there), the sky cells' starts (~10,300 cells of 2 x 2 deg, 4
  // bytes each), the pattern cells' first keys (251^2, 4 bytes each) and a small header (the kd-tree
  // is built at load, when wanted).
  const auto bytes = std::filesystem::file_size(dir + "/catalog.bin");
  EXPECT_LT(bytes, k10.triangles.size() * 36 + k10.stars.size() * 100 + 45000 + 4 * 251 * 251);
}

TEST(Catalog, BadOptionsAreRejected) {
  CatalogBuildOptions o;
  o.pattern_neighbours = 1;
  EXPECT_THROW(o.Check(), InputError);
  o = {};
  o.fov_deg = 0;
  EXPECT_THROW(o.Check(), InputError);
  o = {};
  o.epoch_year = 1000;
  EXPECT_THROW(o.Check(), InputError);
  o = {};
  o.double_star_arcsec = INFINITY;  // overflowed the sky grid's int cell index (UBSan)
  EXPECT_THROW(o.Check(), InputError);
  EXPECT_THROW(LoadSourceCatalog("/nonexistent/catalog"), InputError);
}

}  // namespace
}  // namespace ssiu
