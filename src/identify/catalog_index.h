// The search structures of a SolverCatalog: its triangles sorted by a key of their features, and its
// stars in a FLANN kd-tree. The triangle keys are built once with the catalog and stored in catalog.bin
// (Write / Read), so that a process that loads a catalog does not sort 10^5 triangles each time (issue
// 17: the load went from ~13 to ~2 ms, docs/results.md "Fast start, step 3"); the kd-tree is built from
// the stars at load (well under a millisecond for the 7,569 stars at 16.6 deg), which keeps catalog.bin
// the same bytes for 32- and 64-bit processors (docs/flight.md, "ARM"). The stars are also binned by
// sky cell at load (not stored) for the lookups that allocate nothing.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "core/error.h"
#include "core/types.h"
#include "identify/star_catalog.h"

namespace ssiu {

// Reads n elements of T stored at data + *pos (fixed-width little-endian, as T lies in memory) into
// `out`: with `in_place` (and the bytes aligned for T) a view of them, else a copy; *pos moves past
// them. InputError naming `path` when the bytes end first.
template <typename T>
void ReadCatalogTable(const char* data, size_t bytes, size_t* pos, size_t n, bool in_place, CatalogArray<T>* out,
                      const std::string& path) {
  if (*pos > bytes || n > (bytes - *pos) / sizeof(T)) throw InputError(path, "truncated catalog file");
  const char* p = data + *pos;
  if (in_place && reinterpret_cast<uintptr_t>(p) % alignof(T) == 0) {
    *out = CatalogArray<T>::View(reinterpret_cast<const T*>(p), n);
  } else {
    std::vector<T>& v = out->Own();
    v.resize(n);
    if (n > 0) std::memcpy(static_cast<void*>(v.data()), p, n * sizeof(T));
  }
  *pos += n * sizeof(T);
}

class CatalogIndex {
 public:
  // Triangles sorted by a key of their features: (ratio_a cell, ratio_b cell, ln longest_rad in fine
  // steps), ln the least significant. A box query (ratio tolerance, ln-size tolerance) visits the few
  // (ratio_a, ratio_b) cells it overlaps and, in each, one contiguous run of ln sizes found by binary
  // search. This replaced a FLANN kd-tree radius search, which took 43% of a deep search's time and
  // whose isotropic sphere admitted ratio errors as large as the focal-length range.
  static constexpr double kRatioCell = 0.004;
  static constexpr int kRatioCells = 251;  // ratios in [0, 1]
  static constexpr double kLnStep = 1e-4, kLnMin = -14.0;
  static constexpr int kLnBits = 20;
  // Both clamp before converting: a query box can be far outside [0, 1] or not a number (three
  // nearly coincident centroids give a ratio tolerance of 1e11), and converting such a double to an
  // integer is undefined. NaN goes to cell 0, whose triangles the caller's comparison then rejects.
  static int RatioCell(double r) {
    const double c = std::floor(r / kRatioCell);
    return c >= kRatioCells - 1 ? kRatioCells - 1 : (c > 0 ? static_cast<int>(c) : 0);
  }
  static int64_t LnCell(double ln_l) {
    const double c = std::floor((ln_l - kLnMin) / kLnStep), top = (1 << kLnBits) - 1;
    return c >= top ? static_cast<int64_t>(top) : (c > 0 ? static_cast<int64_t>(c) : 0);
  }
  static uint64_t Key(int ia, int ib, int64_t il) {
    return ((static_cast<uint64_t>(ia) * kRatioCells + static_cast<uint64_t>(ib)) << kLnBits) |
           static_cast<uint64_t>(il);
  }

  // Built from the catalog's stars and triangles.
  explicit CatalogIndex(const SolverCatalog& cat);
  // Restored from Write's bytes for `cat` (the same stars and triangles); InputError naming `path`
  // when they do not fit it. Without `star_tree` the kd-tree is not built (the flight path searches
  // the sky cells; the vector StarsWithin then does too). With `in_place` the tables are searched
  // where they lie in `data` (which must outlive the index), nothing copied or computed.
  CatalogIndex(const SolverCatalog& cat, const char* data, size_t bytes, const std::string& path,
               bool star_tree = true, bool in_place = false);
  ~CatalogIndex();
  CatalogIndex(const CatalogIndex&) = delete;
  CatalogIndex& operator=(const CatalogIndex&) = delete;

  // Appends the index to `out` (keys and triangle order, fixed-width little-endian fields).
  void Write(std::string* out) const;
  // True when built for a catalog of this many stars and triangles.
  bool Fits(const SolverCatalog& cat) const {
    return stars_ == cat.stars.size() && triangle_.size() == cat.triangles.size();
  }
  bool Empty() const { return keys_.empty(); }

  // Calls fn(triangle index) for every triangle with |ratio_a - qa| <= tol_r, |ratio_b - qb| <= tol_r
  // and |ln longest - ql| <= tol_l (the cells overlapping the box; the caller checks the sides). An fn
  // that returns bool ends the walk by returning false.
  template <typename Fn>
  void ForEachInBox(double qa, double qb, double ql, double tol_r, double tol_l, const SolverCatalog& cat,
                    Fn&& fn) const {
    const int64_t l0 = LnCell(ql - tol_l), l1 = LnCell(ql + tol_l);
    for (int ia = RatioCell(qa - tol_r); ia <= RatioCell(qa + tol_r); ++ia) {
      for (int ib = RatioCell(qb - tol_r); ib <= RatioCell(qb + tol_r); ++ib) {
        const uint64_t hi = Key(ia, ib, l1);
        const size_t cell = static_cast<size_t>(ia) * kRatioCells + ib;
        const auto end = keys_.begin() + cell_start_[cell + 1];
        for (auto it = std::lower_bound(keys_.begin() + cell_start_[cell], end, Key(ia, ib, l0));
             it != end && *it <= hi; ++it) {
          const int32_t ti = triangle_[it - keys_.begin()];
          const CatalogTriangle& t = cat.triangles[ti];
          if (!(std::abs(t.ratio_a - qa) <= tol_r && std::abs(t.ratio_b - qb) <= tol_r)) continue;
          if constexpr (std::is_same_v<decltype(fn(ti)), bool>) {
            if (!fn(ti)) return;
          } else {
            fn(ti);
          }
        }
      }
    }
  }

  // Indices of catalog stars within radius_rad of the unit vector u, brightest first (catalog order):
  // a radius search of the kd-tree (allocates its answer and, inside FLANN, its search state).
  std::vector<int> StarsWithin(const Vec3& u, double radius_rad) const;
  // The same stars (the kd-tree's test, to the bit) from the sky cells, into out[0..capacity),
  // allocating nothing: the brightest `capacity` when there are more. Returns how many there are in
  // all (more than capacity: the faintest were left out).
  size_t StarsWithin(const Vec3& u, double radius_rad, int* out, size_t capacity) const;
  // Whether any catalog star is within radius_rad of u (as StarsWithin; allocates nothing).
  bool AnyStarWithin(const Vec3& u, double radius_rad) const;
  // Heap bytes of the sky cells (0 when they are searched in place).
  size_t SkyCellBytes() const { return cell_begin_.HeapBytes() + cell_star_.HeapBytes() + cell_unit_.HeapBytes(); }
  // Heap bytes of every table (0 when all are searched in place; the kd-tree not counted).
  size_t HeapBytes() const {
    return SkyCellBytes() + keys_.HeapBytes() + triangle_.HeapBytes() + cell_start_.HeapBytes();
  }
  // Sky cells: declination bands of kBandRad, each cut into right-ascension cells about as wide.
  static constexpr int kSkyBands = 90;

 private:
  void IndexCells();
  void BandCells();
  void IndexSky(const SolverCatalog& cat);
  void CellUnits(const SolverCatalog& cat);
  // Calls fn(star, unit vector) for every star in a sky cell that a cap of radius_rad about u may touch
  // (a superset of the stars within it), until fn returns false.
  template <typename Fn>
  void ForEachStarNear(const Vec3& u, double radius_rad, Fn&& fn) const;
  // The tables: owned when built, views of the catalog blob when restored in place.
  std::array<int32_t, kSkyBands + 1> band_cell0_{};  // first cell of each band; the cell count last
  CatalogArray<uint32_t> cell_begin_;  // first entry of each cell in cell_star_; one past the end last
  CatalogArray<int32_t> cell_star_;    // star indices by cell, ascending within a cell
  CatalogArray<double> cell_unit_;     // their unit vectors (3 each), in the same order
  CatalogArray<uint64_t> keys_;        // sorted
  CatalogArray<int32_t> triangle_;     // triangle index per key
  CatalogArray<uint32_t> cell_start_;  // first key of each (ratio_a, ratio_b) cell; one past the end last
  size_t stars_ = 0;
  std::vector<double> units_;  // star unit vectors, the kd-tree's points
  struct StarTree;
  std::unique_ptr<StarTree> tree_;
};

}  // namespace ssiu
