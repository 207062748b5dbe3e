#include "identify/catalog_index.h"

#include <algorithm>
#include <cstring>
#include <flann/flann.hpp>

#include "core/error.h"

namespace ssiu {

struct CatalogIndex::StarTree {
  flann::KDTreeSingleIndex<flann::L2<double>> tree;
  explicit StarTree(flann::Matrix<double> points) : tree(points, flann::KDTreeSingleIndexParams(16)) {}
};

namespace {

// Layout version of Write's bytes: a change of the key (the constants above) or of the layout must
// change it, so that an index stored by another version is refused rather than misread. Version 1 also
// stored the star kd-tree in FLANN's own format, which holds size_t and pointers' worth of fields: a
// 32-bit build could not read a tree a 64-bit build wrote. Version 2 stores only fixed-width
// little-endian fields and the tree is built from the stars at load (deterministic: the same tree as
// at build); a version-1 index still loads, its stored tree skipped.
// Version 3 adds the sky cells (the star lookup of the flight path), so that a load builds nothing it
// searches; a version-2 index gets them made at load.
// Version 4 also stores the two tables version 3 filled at load (each pattern cell's first key, the
// sky cells' unit vectors) and starts each table on an 8-byte boundary, so that a blob in ROM is
// searched where it lies (flight/ssiu_flight.h): nothing copied, nothing computed.
constexpr int64_t kIndexVersion = 4;
constexpr int64_t kIndexVersionUnaligned = 3;
constexpr int64_t kIndexVersionWithoutSkyCells = 2;
constexpr int64_t kIndexVersionWithFlannTree = 1;

// Sky cells of 2 x 2 deg (fewer right-ascension cells towards the poles): a field's cap of ~10 deg
// visits ~50 cells.
constexpr int kBands = CatalogIndex::kSkyBands;
constexpr double kBandRad = kPi / kBands;

double DecOf(const Vec3& u) { return std::atan2(u[2], std::hypot(u[0], u[1])); }
double RaFraction(const Vec3& u) { return (std::atan2(u[1], u[0]) + kPi) / (2 * kPi); }  // [0, 1]
int BandOf(double dec) {
  return static_cast<int>(std::clamp(std::floor((dec + kPi / 2) / kBandRad), 0.0, kBands - 1.0));
}
int CellsInBand(int b) {
  const double lo = -kPi / 2 + b * kBandRad, hi = lo + kBandRad;
  const double dec = lo <= 0 && hi >= 0 ? 0.0 : std::min(std::abs(lo), std::abs(hi));
  return std::max(1, static_cast<int>(std::ceil(2 * kPi * std::cos(dec) / kBandRad)));
}
int CellInBand(double ra_fraction, int cells) {
  return static_cast<int>(std::clamp(std::floor(ra_fraction * cells), 0.0, cells - 1.0));
}

// The kd-tree's radius test: FLANN takes the squared chord as a float and keeps a point whose
// squared distance (L2<double>, summed in this order) is below it.
double SquaredChordRadius(double radius_rad) {
  const double chord = 2 * std::sin(std::min(radius_rad, kPi) / 2);
  return static_cast<float>(chord * chord);
}
double SquaredDistance(const Vec3& q, const double* p) {
  double r = 0, d = q[0] - p[0];
  r += d * d;
  d = q[1] - p[1];
  r += d * d;
  d = q[2] - p[2];
  r += d * d;
  return r;
}

flann::Matrix<double> Points(std::vector<double>* units, const SolverCatalog& cat) {
  units->reserve(cat.stars.size() * 3);
  for (const auto& s : cat.stars) units->insert(units->end(), {s.unit[0], s.unit[1], s.unit[2]});
  return flann::Matrix<double>(units->data(), cat.stars.size(), 3);
}

}  // namespace

CatalogIndex::CatalogIndex(const SolverCatalog& cat) : stars_(cat.stars.size()) {
  std::vector<std::pair<uint64_t, int32_t>> kt;
  kt.reserve(cat.triangles.size());
  for (size_t i = 0; i < cat.triangles.size(); ++i) {
    const auto& t = cat.triangles[i];
    kt.push_back(
        {Key(RatioCell(t.ratio_a), RatioCell(t.ratio_b), LnCell(std::log(t.longest_rad))), static_cast<int32_t>(i)});
  }
  std::sort(kt.begin(), kt.end());
  keys_.reserve(kt.size());
  triangle_.reserve(kt.size());
  for (const auto& [k, i] : kt) {
    keys_.push_back(k);
    triangle_.push_back(i);
  }
  IndexCells();
  if (stars_ > 0) {
    tree_ = std::make_unique<StarTree>(Points(&units_, cat));
    tree_->tree.buildIndex();
  }
  IndexSky(cat);
}

void CatalogIndex::BandCells() {
  band_cell0_.fill(0);
  for (int b = 0; b < kBands; ++b) band_cell0_[b + 1] = band_cell0_[b] + CellsInBand(b);
}

void CatalogIndex::IndexSky(const SolverCatalog& cat) {
  BandCells();
  std::vector<std::pair<int32_t, int32_t>> cell_of(stars_);  // (cell, star)
  for (size_t i = 0; i < stars_; ++i) {
    const Vec3& u = cat.stars[i].unit;
    const int b = BandOf(DecOf(u));
    cell_of[i] = {band_cell0_[b] + CellInBand(RaFraction(u), band_cell0_[b + 1] - band_cell0_[b]),
                  static_cast<int32_t>(i)};
  }
  std::sort(cell_of.begin(), cell_of.end());
  std::vector<uint32_t>& begin = cell_begin_.Own();
  std::vector<int32_t>& star = cell_star_.Own();
  begin.assign(static_cast<size_t>(band_cell0_[kBands]) + 1, 0);
  star.resize(stars_);
  for (size_t k = 0; k < stars_; ++k) {
    ++begin[cell_of[k].first + 1];
    star[k] = cell_of[k].second;
  }
  CellUnits(cat);
  for (size_t c = 1; c < begin.size(); ++c) begin[c] += begin[c - 1];
}

// The cells' unit vectors in cell order (a copy for locality: a lookup reads one run of memory).
void CatalogIndex::CellUnits(const SolverCatalog& cat) {
  std::vector<double>& unit = cell_unit_.Own();
  unit.resize(3 * stars_);
  for (size_t k = 0; k < stars_; ++k) {
    const Vec3& u = cat.stars[static_cast<size_t>(cell_star_[k])].unit;
    std::copy_n(u.data(), 3, &unit[3 * k]);
  }
}

template <typename Fn>
void CatalogIndex::ForEachStarNear(const Vec3& u, double radius_rad, Fn&& fn) const {
  if (stars_ == 0 || !u.allFinite() || !(radius_rad >= 0) || u.squaredNorm() == 0) return;
  // A margin far above rounding; the caller's exact test decides.
  const double rho = std::min(radius_rad, kPi) * (1 + 1e-9) + 1e-9;
  const double dec0 = DecOf(u), ra0 = RaFraction(u);
  // Without a pole in the cap, its right ascensions lie within asin(sin rho / cos dec0) of the centre's.
  bool all_ra = dec0 + rho >= kPi / 2 || dec0 - rho <= -kPi / 2;
  double half = 0.5;
  if (!all_ra) {
    const double s = std::sin(rho) / std::cos(dec0);
    if (s < 1) half = std::asin(s) / (2 * kPi) + 1e-9;
    else all_ra = true;
  }
  auto visit = [&](int cell0, int cell1) {  // the cells [cell0, cell1]
    for (uint32_t k = cell_begin_[cell0]; k < cell_begin_[cell1 + 1]; ++k)
      if (!fn(cell_star_[k], &cell_unit_[3 * static_cast<size_t>(k)])) return false;
    return true;
  };
  for (int b = BandOf(dec0 - rho); b <= BandOf(dec0 + rho); ++b) {
    const int c0 = band_cell0_[b], n = band_cell0_[b + 1] - c0;
    const int lo = static_cast<int>(std::floor((ra0 - half) * n)), hi = static_cast<int>(std::floor((ra0 + half) * n));
    bool go = true;
    if (all_ra || hi - lo + 1 >= n) go = visit(c0, c0 + n - 1);
    else if (lo < 0) go = visit(c0 + lo + n, c0 + n - 1) && visit(c0, c0 + hi);
    else if (hi >= n) go = visit(c0 + lo, c0 + n - 1) && visit(c0, c0 + hi - n);
    else go = visit(c0 + lo, c0 + hi);
    if (!go) return;
  }
}

size_t CatalogIndex::StarsWithin(const Vec3& u, double radius_rad, int* out, size_t capacity) const {
  const double r2 = SquaredChordRadius(radius_rad);
  size_t found = 0;
  ForEachStarNear(u, radius_rad, [&](int32_t s, const double* p) {
    if (!(SquaredDistance(u, p) < r2)) return true;
    // Past capacity, out is a max-heap of the brightest (lowest indices) so far.
    if (found < capacity) {
      out[found] = s;
      if (found + 1 == capacity) std::make_heap(out, out + capacity);
    } else if (capacity > 0 && s < out[0]) {
      std::pop_heap(out, out + capacity);
      out[capacity - 1] = s;
      std::push_heap(out, out + capacity);
    }
    ++found;
    return true;
  });
  std::sort(out, out + std::min(found, capacity));
  return found;
}

bool CatalogIndex::AnyStarWithin(const Vec3& u, double radius_rad) const {
  const double r2 = SquaredChordRadius(radius_rad);
  bool any = false;
  ForEachStarNear(u, radius_rad, [&](int32_t, const double* p) { return !(any = SquaredDistance(u, p) < r2); });
  return any;
}

void CatalogIndex::IndexCells() {
  std::vector<uint32_t>& start = cell_start_.Own();
  start.assign(static_cast<size_t>(kRatioCells) * kRatioCells + 1, 0);
  for (size_t cell = 0, k = 0; cell < start.size(); ++cell) {
    while (k < keys_.size() && (keys_[k] >> kLnBits) < cell) ++k;
    start[cell] = static_cast<uint32_t>(k);
  }
}

CatalogIndex::~CatalogIndex() = default;

// Layout (every field fixed-width, little-endian; each table from an 8-byte boundary of the index,
// zero bytes between): version, triangle count (int64), keys (uint64), triangle per key (int32), star
// count (int64), sky cell count (int64), each cell's first entry and one past the last (uint32), the
// stars by cell (int32), the pattern cell count (int64), each pattern cell's first key and one past
// the last (uint32), the sky cells' unit vectors (3 doubles a star, in cell order). The same bytes
// on every processor.
void CatalogIndex::Write(std::string* out) const {
  const size_t start = out->size();
  auto put = [&](const void* p, size_t n) { out->append(static_cast<const char*>(p), n); };
  auto align = [&] { out->resize(start + (out->size() - start + 7) / 8 * 8, '\0'); };
  const int64_t head[2] = {kIndexVersion, static_cast<int64_t>(keys_.size())};
  put(head, sizeof head);
  put(keys_.data(), keys_.size() * sizeof(uint64_t));
  put(triangle_.data(), triangle_.size() * sizeof(int32_t));
  align();
  const int64_t counts[2] = {static_cast<int64_t>(stars_), band_cell0_.back()};
  put(counts, sizeof counts);
  put(cell_begin_.data(), cell_begin_.size() * sizeof(uint32_t));
  put(cell_star_.data(), cell_star_.size() * sizeof(int32_t));
  align();
  const int64_t pattern_cells = static_cast<int64_t>(cell_start_.size());
  put(&pattern_cells, sizeof pattern_cells);
  put(cell_start_.data(), cell_start_.size() * sizeof(uint32_t));
  align();
  put(cell_unit_.data(), cell_unit_.size() * sizeof(double));
}

CatalogIndex::CatalogIndex(const SolverCatalog& cat, const char* data, size_t bytes, const std::string& path,
                           bool star_tree, bool in_place)
    : stars_(cat.stars.size()) {
  size_t pos = 0;
  auto get = [&](void* p, size_t n) {
    if (pos > bytes || n > bytes - pos) throw InputError(path, "truncated catalog index");
    std::memcpy(p, data + pos, n);
    pos += n;
  };
  int64_t head[2];
  get(head, sizeof head);
  const int64_t version = head[0];
  if (version < kIndexVersionWithFlannTree || version > kIndexVersion)
    throw InputError(path, "catalog index of another version (rebuild the catalog)");
  auto align = [&] {
    if (version == kIndexVersion) pos = (pos + 7) / 8 * 8;
  };
  if (head[1] != static_cast<int64_t>(cat.triangles.size()))
    throw InputError(path, "catalog index does not fit its triangles");
  const size_t n_keys = cat.triangles.size();
  ReadCatalogTable(data, bytes, &pos, n_keys, in_place, &keys_, path);
  ReadCatalogTable(data, bytes, &pos, n_keys, in_place, &triangle_, path);
  // Every table is checked as read, so that no search can step outside one (the blob's CRC, which
  // meta.json and the flight interface check, vouches for the rest). Read through const references:
  // a view is never copied.
  const CatalogArray<uint64_t>& keys = keys_;
  const CatalogArray<int32_t>& tri = triangle_;
  for (size_t i = 0; i < n_keys; ++i) {
    if ((i > 0 && keys[i] < keys[i - 1]) || tri[i] < 0 || tri[i] >= static_cast<int32_t>(n_keys))
      throw InputError(path, "corrupt catalog index (keys unsorted or triangle out of range)");
  }
  align();
  int64_t stars = 0;
  get(&stars, sizeof stars);
  if (stars != static_cast<int64_t>(stars_)) throw InputError(path, "catalog index does not fit its stars");
  if (version == kIndexVersionWithFlannTree) {
    // The byte count of FLANN's tree, and the tree (not read: its layout depends on the writer's size_t).
    int64_t tree_bytes = 0;
    get(&tree_bytes, sizeof tree_bytes);
    if (tree_bytes < 0 || static_cast<uint64_t>(tree_bytes) != bytes - pos)
      throw InputError(path, "catalog index does not fit its stars");
    pos = bytes;
  }
  if (version >= kIndexVersionUnaligned) {
    BandCells();
    int64_t cells = 0;
    get(&cells, sizeof cells);
    if (cells != band_cell0_.back()) throw InputError(path, "catalog index: sky cells of another layout");
    ReadCatalogTable(data, bytes, &pos, static_cast<size_t>(cells) + 1, in_place, &cell_begin_, path);
    ReadCatalogTable(data, bytes, &pos, stars_, in_place, &cell_star_, path);
    const CatalogArray<uint32_t>& begin = cell_begin_;
    const CatalogArray<int32_t>& star = cell_star_;
    bool ok = begin.front() == 0 && begin.back() == stars_;
    for (size_t c = 1; ok && c < begin.size(); ++c) ok = begin[c] >= begin[c - 1];
    for (size_t k = 0; ok && k < stars_; ++k) ok = star[k] >= 0 && static_cast<size_t>(star[k]) < stars_;
    if (!ok) throw InputError(path, "corrupt catalog index (sky cells)");
  }
  if (version == kIndexVersion) {
    align();
    int64_t pattern_cells = 0;
    get(&pattern_cells, sizeof pattern_cells);
    if (pattern_cells != static_cast<int64_t>(kRatioCells) * kRatioCells + 1)
      throw InputError(path, "catalog index: pattern cells of another layout");
    ReadCatalogTable(data, bytes, &pos, static_cast<size_t>(pattern_cells), in_place, &cell_start_, path);
    // Each cell's run holds exactly its own keys.
    const CatalogArray<uint32_t>& start = cell_start_;
    bool ok = start.front() == 0 && start.back() == n_keys;
    for (size_t c = 0; ok && c + 1 < start.size(); ++c) {
      ok = start[c + 1] >= start[c] && start[c + 1] <= n_keys;
      for (uint32_t k = start[c]; ok && k < start[c + 1]; ++k) ok = (keys[k] >> kLnBits) == c;
    }
    if (!ok) throw InputError(path, "corrupt catalog index (pattern cells)");
    align();
    ReadCatalogTable(data, bytes, &pos, 3 * stars_, in_place, &cell_unit_, path);
    // The cells' unit vectors are their stars' (to the bit: the lookups must equal the kd-tree's).
    const CatalogArray<double>& unit = cell_unit_;
    const CatalogArray<int32_t>& star = cell_star_;
    for (size_t k = 0; ok && k < stars_; ++k) {
      const Vec3& u = cat.stars[static_cast<size_t>(star[k])].unit;
      ok = unit[3 * k] == u[0] && unit[3 * k + 1] == u[1] && unit[3 * k + 2] == u[2];
    }
    if (!ok) throw InputError(path, "corrupt catalog index (sky cells' unit vectors)");
  } else {
    IndexCells();
    if (version == kIndexVersionUnaligned) CellUnits(cat);
  }
  if (pos != bytes) throw InputError(path, "catalog index does not fit its stars (bytes after its end)");
  if (version <= kIndexVersionWithoutSkyCells) IndexSky(cat);
  if (star_tree && stars_ > 0) {
    tree_ = std::make_unique<StarTree>(Points(&units_, cat));
    tree_->tree.buildIndex();
  }
}

std::vector<int> CatalogIndex::StarsWithin(const Vec3& u, double radius_rad) const {
  std::vector<int> out;
  if (!tree_) {  // loaded without the kd-tree: the same stars from the sky cells
    out.resize(stars_);
    out.resize(std::min(StarsWithin(u, radius_rad, out.data(), out.size()), out.size()));
    return out;
  }
  double q[3] = {u[0], u[1], u[2]};
  flann::Matrix<double> qm(q, 1, 3);
  std::vector<std::vector<int>> idx;
  std::vector<std::vector<double>> dist;
  flann::SearchParams sp;
  sp.sorted = false;
  tree_->tree.radiusSearch(qm, idx, dist, static_cast<float>(SquaredChordRadius(radius_rad)), sp);
  out = std::move(idx[0]);
  std::sort(out.begin(), out.end());  // brightest first (catalog order)
  return out;
}

}  // namespace ssiu
