// The catalog stored ready to use (issue 17, fast start): catalog.bin carries the stars' unit vectors,
// the triangles' features and the search index, and a loaded catalog is the built one bit for bit, its
// index answering every query as one built anew; a catalog.bin of the format before (3: vertices only,
// features and index rebuilt at load) still loads and solves the same; a stored index that does not
// fit its catalog is refused; an index of version 1 (with FLANN's tree, skipped) still loads.
#include "identify/catalog_index.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "core/attitude.h"
#include "core/catalog.h"
#include "core/error.h"
#include "core/json.h"
#include "core/output.h"
#include "core/rng.h"
#include "identify/identify.h"
#include "identify/synthetic.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

const SolverCatalog& Built20() {
  static const SolverCatalog cat = [] {
    CatalogBuildOptions o;
    o.fov_deg = 20;
    return BuildSolverCatalog(LoadSourceCatalog(DefaultBscPath()), o);
  }();
  return cat;
}

// Writes `bin` as DIR/catalog.bin with a meta.json recording its size and CRC-32 (what the integrity
// check compares), so that a damaged or old-format file reaches the parser.
void WriteCatalogDir(const std::string& dir, const std::string& bin, double fov_deg) {
  WriteFileAtomic(dir + "/catalog.bin", bin);
  WriteJsonFile(dir + "/meta.json", Json{{"fov_deg", fov_deg},
                                         {"catalog_bin_bytes", bin.size()},
                                         {"catalog_bin_crc32", Crc32(bin.data(), bin.size())}});
}

std::string ReadCatalogBin(const std::string& dir) {
  std::ifstream in(dir + "/catalog.bin", std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Where the index starts in catalog.bin: after the header, the stars and the triangles.
size_t Align8(size_t n) { return (n + 7) / 8 * 8; }
size_t IndexOffset(const SolverCatalog& c) {
  return Align8(8 + 5 * 8 + 5 * 8 + c.source.size()) + c.stars.size() * 72 + c.triangles.size() * 24;
}

// Where each table of the index (version 4) starts, in catalog.bin; `cells` the sky cells' count.
struct IndexLayout {
  size_t at, keys, triangle, star_count, cell_begin, cell_star, pattern_cells, cell_start, cell_unit, end;
};
IndexLayout LayoutOf(const SolverCatalog& c, size_t cells) {
  IndexLayout l;
  const size_t n = c.triangles.size(), stars = c.stars.size();
  l.at = IndexOffset(c);
  l.keys = l.at + 16;
  l.triangle = l.keys + 8 * n;
  l.star_count = Align8(l.triangle + 4 * n);
  l.cell_begin = l.star_count + 16;  // the star and sky cell counts
  l.cell_star = l.cell_begin + 4 * (cells + 1);
  l.pattern_cells = Align8(l.cell_star + 4 * stars);
  l.cell_start = l.pattern_cells + 8;
  l.cell_unit = Align8(l.cell_start + 4 * (CatalogIndex::kRatioCells * CatalogIndex::kRatioCells + 1));
  l.end = l.cell_unit + 24 * stars;
  return l;
}
size_t SkyCells(const std::string& bin, const SolverCatalog& c) {
  int64_t cells = 0;
  std::memcpy(&cells, bin.data() + LayoutOf(c, 0).star_count + 8, 8);
  return static_cast<size_t>(cells);
}

// An index of an older version (1 or 2: keys, triangle order and star count, unaligned) in front of
// `good`'s stars and triangles.
std::string OlderIndex(const std::string& good, const SolverCatalog& c, int64_t version) {
  const IndexLayout l = LayoutOf(c, 0);
  std::string out = good.substr(0, l.keys);
  std::memcpy(out.data() + l.at, &version, 8);
  out += good.substr(l.keys, 12 * c.triangles.size());
  const int64_t stars = static_cast<int64_t>(c.stars.size());
  out.append(reinterpret_cast<const char*>(&stars), 8);
  return out;
}

// catalog.bin of format 3 (before issue 17): header, per star id + ra, dec, mag, pm_ra, pm_dec,
// per triangle its three vertices.
std::string FormatThree(const SolverCatalog& c) {
  std::string out;
  auto put = [&](const void* p, size_t n) { out.append(static_cast<const char*>(p), n); };
  put("SSIUCAT3", 8);
  const double hdr[5] = {c.epoch_year, c.fov_deg, c.mag_max, c.double_star_arcsec, c.build_time_s};
  put(hdr, sizeof hdr);
  const int64_t counts[5] = {static_cast<int64_t>(c.stars.size()), static_cast<int64_t>(c.triangles.size()),
                             c.num_pattern_stars, c.pattern_neighbours, static_cast<int64_t>(c.source.size())};
  put(counts, sizeof counts);
  put(c.source.data(), c.source.size());
  for (const auto& s : c.stars) {
    const double d[5] = {s.ra_rad, s.dec_rad, s.mag, s.pm_ra_rad_per_yr, s.pm_dec_rad_per_yr};
    put(&s.id, sizeof s.id);
    put(d, sizeof d);
  }
  for (const auto& t : c.triangles) put(t.v.data(), sizeof t.v);
  return out;
}

// Stars and triangles equal to the last bit (the index is compared by its answers).
void ExpectSameCatalog(const SolverCatalog& a, const SolverCatalog& b) {
  ASSERT_EQ(a.stars.size(), b.stars.size());
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  for (size_t i = 0; i < a.stars.size(); ++i) {
    ASSERT_EQ(a.stars[i].id, b.stars[i].id) << i;
    ASSERT_EQ(a.stars[i].unit, b.stars[i].unit) << "star " << i;
  }
  for (size_t i = 0; i < a.triangles.size(); ++i) {
    const CatalogTriangle &s = a.triangles[i], &t = b.triangles[i];
    ASSERT_TRUE(s.v == t.v && s.longest_rad == t.longest_rad && s.ratio_a == t.ratio_a && s.ratio_b == t.ratio_b)
        << "triangle " << i;
  }
}

TEST(CatalogIndex, LoadedCatalogIsTheBuiltOneAndItsStoredIndexAnswersAsANewOne) {
  const SolverCatalog& built = Built20();
  ASSERT_TRUE(built.index);
  const std::string dir = testing::TempDir("catalog_index_stored");
  SaveSolverCatalog(built, dir);
  const SolverCatalog back = LoadSolverCatalog(dir);
  ExpectSameCatalog(built, back);
  ASSERT_TRUE(back.index && back.index->Fits(back));
  const CatalogIndex fresh(back);
  Rng rng(17);
  for (int i = 0; i < 200; ++i) {
    // Star cones around random directions; triangle boxes around real triangles' features.
    const Vec3 u = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform()).toRotationMatrix().col(2);
    const double r = rng.Uniform(0.01, 0.3);
    const std::vector<int> got = back.index->StarsWithin(u, r), want = fresh.StarsWithin(u, r);
    EXPECT_EQ(got, want) << "query " << i;
    for (int s : want) EXPECT_GT(u.dot(back.stars[s].unit), std::cos(r) - 1e-12);
    const CatalogTriangle& t = back.triangles[static_cast<size_t>(rng.Uniform(0, back.triangles.size() - 1))];
    std::vector<int> tg, tw;
    back.index->ForEachInBox(t.ratio_a, t.ratio_b, std::log(t.longest_rad), 0.01, 0.02, back,
                             [&](int k) { tg.push_back(k); });
    fresh.ForEachInBox(t.ratio_a, t.ratio_b, std::log(t.longest_rad), 0.01, 0.02, back,
                       [&](int k) { tw.push_back(k); });
    EXPECT_EQ(tg, tw) << "query " << i;
    EXPECT_FALSE(tw.empty());  // the triangle itself at least
  }
}

// A box far outside the features' range (three nearly coincident centroids give a ratio tolerance
// near 1e11) or not a number is a defined query: the box that spans everything visits every triangle
// once, a NaN one visits none. (Converting such a bound to a cell index unclamped is undefined, which
// the sanitizer build reports.)
TEST(CatalogIndex, BoxQueryFarOutsideTheFeaturesRangeIsDefined) {
  const SolverCatalog& cat = Built20();
  ASSERT_TRUE(cat.index);
  std::vector<int> seen;
  cat.index->ForEachInBox(-2.7e11, 5e11, 0.0, 1e12, 1e12, cat, [&](int k) { seen.push_back(k); });
  std::sort(seen.begin(), seen.end());
  EXPECT_EQ(seen.size(), cat.triangles.size());
  EXPECT_TRUE(std::adjacent_find(seen.begin(), seen.end()) == seen.end());
  int visited = 0;
  const double nan = std::nan("");
  cat.index->ForEachInBox(nan, 0.5, -1.0, 0.01, 0.02, cat, [&](int) { ++visited; });
  cat.index->ForEachInBox(0.5, 0.5, -1.0, nan, 0.02, cat, [&](int) { ++visited; });
  EXPECT_EQ(visited, 0);
}

// The sky-cell lookup (no allocation) answers as the kd-tree's radius search, to the star: random
// cones, cones at the poles and across right ascension 0/360, radii at a star's own distance (the
// boundary), the whole sky; more stars than the room: the brightest; NaN: none.
TEST(CatalogIndex, SkyCellLookupIsTheKdTreeSearch) {
  const SolverCatalog& cat = Built20();
  const CatalogIndex& index = *cat.index;
  std::vector<int> buf(cat.stars.size());
  auto cells = [&](const Vec3& u, double r) {
    const size_t n = index.StarsWithin(u, r, buf.data(), buf.size());
    return std::vector<int>(buf.begin(), buf.begin() + n);
  };
  Rng rng(23);
  std::vector<std::pair<Vec3, double>> queries;
  for (int i = 0; i < 3000; ++i) {
    const Vec3 u = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform()).toRotationMatrix().col(2);
    queries.push_back({u, rng.Uniform(0.0, 0.4)});
    queries.push_back({u, rng.Uniform(0.0, 0.002)});
    // A star at the edge: the radius of its own angle (either side of FLANN's float radius).
    const Vec3& v = cat.stars[static_cast<size_t>(rng.Uniform(0, cat.stars.size() - 1))].unit;
    const Vec3 w = (v + 0.05 * u).normalized();
    queries.push_back({w, std::acos(std::clamp(w.dot(v), -1.0, 1.0))});
  }
  for (const Vec3& u : {Vec3(0, 0, 1), Vec3(0, 0, -1), Vec3(1, 0, 0), Vec3(-1, 1e-12, 0), Vec3(-1, -1e-12, 0),
                        Vec3(0.3, 0, 0.95).normalized(), Vec3(-0.99, 0.01, 0.1).normalized()}) {
    for (double r : {0.0, 0.05, 0.2, 1.0, 1.6, 3.2, 4.0}) queries.push_back({u, r});
  }
  for (const auto& [u, r] : queries) {
    const std::vector<int> want = index.StarsWithin(u, r);
    ASSERT_EQ(cells(u, r), want) << u.transpose() << " r " << r;
    EXPECT_EQ(index.AnyStarWithin(u, r), !want.empty());
  }
  // Room for 5: the 5 brightest (lowest indices), and the count of all.
  const Vec3 u = cat.stars[0].unit;
  const std::vector<int> all = index.StarsWithin(u, 0.3);
  ASSERT_GT(all.size(), 5u);
  int five[5];
  EXPECT_EQ(index.StarsWithin(u, 0.3, five, 5), all.size());
  EXPECT_EQ(std::vector<int>(five, five + 5), std::vector<int>(all.begin(), all.begin() + 5));
  EXPECT_EQ(index.StarsWithin(u, 0.3, nullptr, 0), all.size());
  EXPECT_EQ(index.StarsWithin(Vec3(std::nan(""), 0, 1), 0.3, five, 5), 0u);
  EXPECT_EQ(index.StarsWithin(u, std::nan(""), five, 5), 0u);
  EXPECT_GT(index.SkyCellBytes(), cat.stars.size() * 28);
}

TEST(CatalogIndex, FormatThreeCatalogStillLoadsAndSolvesTheSame) {
  const SolverCatalog& built = Built20();
  const std::string dir = testing::TempDir("catalog_index_v3");
  WriteCatalogDir(dir, FormatThree(built), built.fov_deg);
  const SolverCatalog old = LoadSolverCatalog(dir);
  ExpectSameCatalog(built, old);
  ASSERT_TRUE(old.index);
  const StarIdentifier a(built), b(old);
  const Camera cam = MakeCamera(1024, 1024, 20);
  for (int i = 0; i < 5; ++i) {
    Rng rng(300 + i);
    const Quat q = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform());
    const auto f = testing::MakeSyntheticFrame(built, cam, q, testing::SyntheticOptions{}, &rng);
    const Identification ra = a.Identify(f.centroids, cam, IdentifyOptions{}),
                         rb = b.Identify(f.centroids, cam, IdentifyOptions{});
    EXPECT_EQ(ra.status, SolveStatus::kSolved);
    EXPECT_LT(AttitudeErrorRad(ra.q_inertial_from_sensor, q) * kRadToArcsec, 60);  // 0.2 px of 70"
    EXPECT_EQ(ra.status, rb.status);
    EXPECT_EQ(ra.q_inertial_from_sensor.coeffs(), rb.q_inertial_from_sensor.coeffs());
    EXPECT_EQ(ra.matches.size(), rb.matches.size());
  }
}

TEST(CatalogIndex, StoredIndexThatDoesNotFitIsRefused) {
  const SolverCatalog& built = Built20();
  const std::string dir = testing::TempDir("catalog_index_bad");
  SaveSolverCatalog(built, dir);
  const std::string good = ReadCatalogBin(dir);
  // The index's first field is its version, then the triangle count.
  const size_t at = IndexOffset(built);
  int64_t head[2];
  std::memcpy(head, good.data() + at, sizeof head);
  ASSERT_EQ(head[1], static_cast<int64_t>(built.triangles.size()));
  std::string bad = good;
  const int64_t other_version = head[0] + 1;
  std::memcpy(bad.data() + at, &other_version, 8);
  WriteCatalogDir(dir, bad, built.fov_deg);
  EXPECT_THAT(testing::ErrorOf([&] { LoadSolverCatalog(dir); }), HasSubstr("catalog index of another version"));
  const IndexLayout l = LayoutOf(built, SkyCells(good, built));
  ASSERT_EQ(good.size(), l.end);
  bad = good.substr(0, good.size() - 4);  // the last table cut short (size and CRC made to agree)
  WriteCatalogDir(dir, bad, built.fov_deg);
  EXPECT_THAT(testing::ErrorOf([&] { LoadSolverCatalog(dir); }), HasSubstr("truncated catalog"));
  bad = good + std::string(8, '\0');  // bytes after the index's end
  WriteCatalogDir(dir, bad, built.fov_deg);
  EXPECT_THAT(testing::ErrorOf([&] { LoadSolverCatalog(dir); }), HasSubstr("does not fit its stars"));
  bad = good;  // another star count
  const int64_t stars = static_cast<int64_t>(built.stars.size()) + 1;
  std::memcpy(bad.data() + l.star_count, &stars, 8);
  WriteCatalogDir(dir, bad, built.fov_deg);
  EXPECT_THAT(testing::ErrorOf([&] { LoadSolverCatalog(dir); }), HasSubstr("does not fit its stars"));
  bad = good;  // a star of the sky cells out of range (the last entry)
  const int32_t no_star = static_cast<int32_t>(built.stars.size());
  std::memcpy(bad.data() + l.cell_star + 4 * (built.stars.size() - 1), &no_star, 4);
  WriteCatalogDir(dir, bad, built.fov_deg);
  EXPECT_THAT(testing::ErrorOf([&] { LoadSolverCatalog(dir); }), HasSubstr("sky cells"));
  // A pattern cell's run moved by one key: a key outside its cell.
  bad = good;
  uint32_t start = 0;
  size_t cell = 1;
  for (;; ++cell) {  // the first cell after a non-empty one
    uint32_t prev = 0;
    std::memcpy(&prev, good.data() + l.cell_start + 4 * (cell - 1), 4);
    std::memcpy(&start, good.data() + l.cell_start + 4 * cell, 4);
    if (start > prev) break;
  }
  --start;
  std::memcpy(bad.data() + l.cell_start + 4 * cell, &start, 4);
  WriteCatalogDir(dir, bad, built.fov_deg);
  EXPECT_THAT(testing::ErrorOf([&] { LoadSolverCatalog(dir); }), HasSubstr("pattern cells"));
  // A sky cell's unit vector that is not its star's.
  bad = good;
  const double off = 0.5;
  std::memcpy(bad.data() + l.cell_unit + 8, &off, 8);
  WriteCatalogDir(dir, bad, built.fov_deg);
  EXPECT_THAT(testing::ErrorOf([&] { LoadSolverCatalog(dir); }), HasSubstr("unit vectors"));
  // Two keys swapped: no longer sorted.
  bad = good;
  std::memcpy(bad.data() + at + 16, good.data() + at + 24, 8);
  std::memcpy(bad.data() + at + 24, good.data() + at + 16, 8);
  if (bad != good) {
    WriteCatalogDir(dir, bad, built.fov_deg);
    EXPECT_THAT(testing::ErrorOf([&] { LoadSolverCatalog(dir); }), HasSubstr("keys unsorted"));
  }
}

// Index version 1 stored the star kd-tree in FLANN's own format, whose fields are the writer's size_t:
// a 32-bit processor cannot read what a 64-bit one wrote. Such a catalog.bin still loads anywhere: the
// stored tree (here bytes no FLANN could read) is skipped and the tree built from the stars, so that
// the catalog answers as the built one. Versions 2 and 3 (fixed-width fields only; 3 adds the sky
// cells) are the same bytes on every processor: the size of each part is checked here, so that
// nothing sized by the processor creeps in. A version-2 index gets its sky cells made at load.
TEST(CatalogIndex, VersionOneIndexLoadsWithItsStoredTreeSkipped) {
  const SolverCatalog& built = Built20();
  const std::string dir = testing::TempDir("catalog_index_v1");
  SaveSolverCatalog(built, dir);
  const std::string good = ReadCatalogBin(dir);
  const size_t cells = SkyCells(good, built);
  EXPECT_GT(cells, 10000u);  // 2 x 2 deg over the sphere
  ASSERT_EQ(good.size(), LayoutOf(built, cells).end);
  {
    const std::string v2 = OlderIndex(good, built, 2);
    WriteCatalogDir(dir, v2, built.fov_deg);
    const SolverCatalog back = LoadSolverCatalog(dir);
    const Vec3 u = back.stars[3].unit;
    std::vector<int> a(200), b(200);
    const size_t na = back.index->StarsWithin(u, 0.1, a.data(), a.size());
    const size_t nb = built.index->StarsWithin(u, 0.1, b.data(), b.size());
    ASSERT_EQ(na, nb);
    ASSERT_GT(na, 0u);
    a.resize(std::min(na, a.size()));
    b.resize(std::min(nb, b.size()));
    EXPECT_EQ(a, b);
  }
  // Parsed without the kd-tree (the flight path): the vector lookup answers from the sky cells, the same.
  const SolverCatalog lean = ParseSolverCatalog(good.data(), good.size(), "lean", /*star_tree=*/false);
  for (int k = 0; k < 20; ++k) {
    const Vec3 u = built.stars[static_cast<size_t>(k * 37) % built.stars.size()].unit;
    EXPECT_EQ(lean.index->StarsWithin(u, 0.12), built.index->StarsWithin(u, 0.12));
  }
  std::string v1 = OlderIndex(good, built, 1);
  const size_t v2_end = v1.size();
  const int64_t version = 1, tree_bytes = 1000;
  v1.append(reinterpret_cast<const char*>(&tree_bytes), 8);
  v1.append(static_cast<size_t>(tree_bytes), '\xff');
  WriteCatalogDir(dir, v1, built.fov_deg);
  const SolverCatalog back = LoadSolverCatalog(dir);
  ExpectSameCatalog(built, back);
  ASSERT_TRUE(back.index && back.index->Fits(back));
  const Vec3 u = back.stars[0].unit;
  EXPECT_EQ(back.index->StarsWithin(u, 0.1), built.index->StarsWithin(u, 0.1));
  EXPECT_FALSE(back.index->StarsWithin(u, 0.1).empty());
  // A version-1 tree's byte count that does not reach the end is refused, never read.
  std::memcpy(v1.data() + v2_end, &version, 8);
  WriteCatalogDir(dir, v1, built.fov_deg);
  EXPECT_THAT(testing::ErrorOf([&] { LoadSolverCatalog(dir); }), HasSubstr("does not fit its stars"));
}

}  // namespace
}  // namespace ssiu
