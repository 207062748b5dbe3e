#include "identify/catalog_index.h"

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
constexpr int64_t kIndexVersion = 2;
constexpr int64_t kIndexVersionWithFlannTree = 1;

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
}

void CatalogIndex::IndexCells() {
  cell_start_.assign(static_cast<size_t>(kRatioCells) * kRatioCells + 1, 0);
  for (size_t cell = 0, k = 0; cell < cell_start_.size(); ++cell) {
    while (k < keys_.size() && (keys_[k] >> kLnBits) < cell) ++k;
    cell_start_[cell] = static_cast<uint32_t>(k);
  }
}

CatalogIndex::~CatalogIndex() = default;

// Layout (every field fixed-width, little-endian): version, triangle count (int64), keys (uint64),
// triangle per key (int32), star count (int64). The same bytes on every processor.
void CatalogIndex::Write(std::string* out) const {
  auto put = [&](const void* p, size_t n) { out->append(static_cast<const char*>(p), n); };
  const int64_t head[2] = {kIndexVersion, static_cast<int64_t>(keys_.size())};
  put(head, sizeof head);
  put(keys_.data(), keys_.size() * sizeof(uint64_t));
  put(triangle_.data(), triangle_.size() * sizeof(int32_t));
  const int64_t stars = static_cast<int64_t>(stars_);
  put(&stars, sizeof stars);
}

CatalogIndex::CatalogIndex(const SolverCatalog& cat, const char* data, size_t bytes, const std::string& path)
    : stars_(cat.stars.size()) {
  size_t pos = 0;
  auto get = [&](void* p, size_t n) {
    if (n > bytes - pos) throw InputError(path, "truncated catalog index");
    std::memcpy(p, data + pos, n);
    pos += n;
  };
  int64_t head[2];
  get(head, sizeof head);
  if (head[0] != kIndexVersion && head[0] != kIndexVersionWithFlannTree)
    throw InputError(path, "catalog index of another version (rebuild the catalog)");
  if (head[1] != static_cast<int64_t>(cat.triangles.size()))
    throw InputError(path, "catalog index does not fit its triangles");
  keys_.resize(cat.triangles.size());
  triangle_.resize(cat.triangles.size());
  get(keys_.data(), keys_.size() * sizeof(uint64_t));
  get(triangle_.data(), triangle_.size() * sizeof(int32_t));
  for (size_t i = 0; i < keys_.size(); ++i) {
    if ((i > 0 && keys_[i] < keys_[i - 1]) || triangle_[i] < 0 || triangle_[i] >= static_cast<int32_t>(keys_.size()))
      throw InputError(path, "corrupt catalog index (keys unsorted or triangle out of range)");
  }
  IndexCells();
  int64_t stars = 0;
  get(&stars, sizeof stars);
  if (stars != static_cast<int64_t>(stars_)) throw InputError(path, "catalog index does not fit its stars");
  if (head[0] == kIndexVersionWithFlannTree) {
    // The byte count of FLANN's tree, and the tree (not read: its layout depends on the writer's size_t).
    int64_t tree_bytes = 0;
    get(&tree_bytes, sizeof tree_bytes);
    if (tree_bytes < 0 || static_cast<uint64_t>(tree_bytes) != bytes - pos)
      throw InputError(path, "catalog index does not fit its stars");
    pos = bytes;
  }
  if (pos != bytes) throw InputError(path, "catalog index does not fit its stars (bytes after its end)");
  if (stars_ == 0) return;
  tree_ = std::make_unique<StarTree>(Points(&units_, cat));
  tree_->tree.buildIndex();
}

std::vector<int> CatalogIndex::StarsWithin(const Vec3& u, double radius_rad) const {
  std::vector<int> out;
  if (!tree_) return out;
  double q[3] = {u[0], u[1], u[2]};
  flann::Matrix<double> qm(q, 1, 3);
  std::vector<std::vector<int>> idx;
  std::vector<std::vector<double>> dist;
  const double chord = 2 * std::sin(std::min(radius_rad, kPi) / 2);
  flann::SearchParams sp;
  sp.sorted = false;
  tree_->tree.radiusSearch(qm, idx, dist, static_cast<float>(chord * chord), sp);
  out = std::move(idx[0]);
  std::sort(out.begin(), out.end());  // brightest first (catalog order)
  return out;
}

}  // namespace ssiu
