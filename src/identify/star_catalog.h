// The solver's star catalog: a source catalog (xplanet BSC, binary BSC5, KStars Hipparcos/Tycho)
// brought to an epoch with proper motion, close doubles merged, plus the triangle pattern index
// for one field of view. Built once, saved to a directory, loaded by `ssiu solve` / `ssiu track`.
//
//   SolverCatalog cat = BuildSolverCatalog(LoadSourceCatalog(path, options), options);
//   SaveSolverCatalog(cat, "build/catalog/bsc_16.6");
//
// star_id: HR number for BSC sources; for KStars stars.dat (which carries no catalog number) the
// HR number of the BSC star it coincides with when one is given, else 1000000 + the star's data-row
// ordinal in stars.dat (1-based, comment lines not counted). See docs/identify.md.
#pragma once

#include <array>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "core/catalog.h"
#include "core/types.h"

namespace ssiu {

constexpr StarId kKstarsIdOffset = 1000000;

struct CatalogBuildOptions {
  double fov_deg = 16.6;  // horizontal field of view the pattern index is built for (the largest)
  // Unknown field of view (solve --fov-range-deg): the smallest FOV served; 0 = fov_deg. Stars and
  // pattern-star density are chosen for it, and the index gets one level of triangles per factor
  // sqrt(2) of FOV up to fov_deg (docs/identify.md, "Unknown field of view").
  double fov_min_deg = 0.0;
  double mag_max = 0.0;             // faintest star kept; 0 = chosen from the FOV (stars_per_fov)
  double epoch_year = 2025.0;       // proper motion applied from J2000.0 to this epoch (when known)
  double double_star_arcsec = 0.0;  // merge stars closer than this; 0 = 3 pixels of a 1024-px sensor
  int pattern_stars_per_fov = 10;   // pattern stars kept per cap of radius fov/2 (uniform sky cover)
  double stars_per_fov = 40.0;      // auto mag limit: mean stars in a cap of diameter fov_deg
  double min_side_frac = 0.02;      // triangle sides shorter than this fraction of the FOV are skipped
  // Triangles per pattern star: only those among the star and its K nearest pattern neighbours
  // (within the FOV), which keeps the index near N * K(K-1)/2 instead of growing with the square of
  // the neighbours in a field; 0 = every triangle that fits in the FOV.
  int pattern_neighbours = 10;
  // And with its B brightest pattern stars in the FOV beyond those K (the union), so that a field's
  // few bright stars form indexed triangles where fainter pattern stars crowd them out of the K
  // nearest (ESA's false-star scenes with four true stars: 98 -> 116 of 145 solved with B = 5,
  // docs/identify.md). 0 = the K nearest only.
  int pattern_bright_neighbours = 5;
  void Check() const;  // throws InputError naming the field
  double FovMinDeg() const { return fov_min_deg > 0 ? fov_min_deg : fov_deg; }
};

// A triangle of catalog stars. Vertices are ordered by the side opposite them (v[0] opposite the
// shortest side), so that sorted side lengths give the vertex correspondence.
struct CatalogTriangle {
  std::array<int32_t, 3> v{};      // indices into SolverCatalog::stars
  float longest_rad = 0;           // longest side (angle)
  float ratio_a = 0, ratio_b = 0;  // shortest / longest, middle / longest
};

class CatalogIndex;  // identify/catalog_index.h

// A catalog table that owns its elements, or views them where they lie (a catalog blob in ROM or
// mapped storage, docs/flight.md "Catalog"): the flight path searches the blob's tables in place,
// with nothing copied. Reads are a const array's; writes go through Own(), which copies a view first,
// so that a builder or a test that changes a loaded catalog never writes into the blob. A view's
// bytes must outlive it and its copies.
template <typename T>
class CatalogArray {
 public:
  CatalogArray() = default;
  CatalogArray(std::initializer_list<T> v) : own_(v) {}
  CatalogArray& operator=(std::vector<T> v) {
    own_ = std::move(v);
    view_ = nullptr, n_ = 0;
    return *this;
  }
  static CatalogArray View(const T* data, size_t n) {
    CatalogArray a;
    a.view_ = data, a.n_ = n;
    return a;
  }

  size_t size() const { return view_ ? n_ : own_.size(); }
  bool empty() const { return size() == 0; }
  const T* data() const { return view_ ? view_ : own_.data(); }
  const T* begin() const { return data(); }
  const T* end() const { return data() + size(); }
  const T& operator[](size_t i) const { return data()[i]; }
  const T& front() const { return data()[0]; }
  const T& back() const { return data()[size() - 1]; }
  // Bytes this table holds on the heap (0 for a view).
  size_t HeapBytes() const { return own_.capacity() * sizeof(T); }

  // Writes, through Own() alone (a view is copied into owned storage first): element access is
  // read-only, so that no read of a view copies it.
  std::vector<T>& Own() {
    if (view_) {
      own_.assign(view_, view_ + n_);
      view_ = nullptr, n_ = 0;
    }
    return own_;
  }
  void push_back(const T& v) { Own().push_back(v); }
  void resize(size_t n) { Own().resize(n); }
  void reserve(size_t n) { Own().reserve(n); }
  void assign(size_t n, const T& v) { Own().assign(n, v); }
  void clear() { Own().clear(); }

 private:
  std::vector<T> own_;
  const T* view_ = nullptr;
  size_t n_ = 0;
};

struct SolverCatalog {
  std::string source;
  double epoch_year = 2000.0;
  double fov_deg = 0;      // largest horizontal FOV served
  double fov_min_deg = 0;  // smallest (= fov_deg for a fixed FOV; meta.json `fov_min_deg`)
  double mag_max = 0;
  double double_star_arcsec = 0;
  CatalogArray<CatalogStar> stars;  // brightest first, positions at epoch_year
  CatalogArray<CatalogTriangle> triangles;
  int num_pattern_stars = 0;
  int pattern_neighbours = 0;  // CatalogBuildOptions::pattern_neighbours the index was built with
  double build_time_s = 0;
  // The search structures (triangles by feature, stars in a kd-tree): made by BuildSolverCatalog,
  // stored in catalog.bin and read back by LoadSolverCatalog; null = StarIdentifier builds them.
  // Shared by copies: whoever changes `stars` or `triangles` must reset it.
  std::shared_ptr<const CatalogIndex> index;

  // Pattern index on disk: per triangle its vertices and features, its key and its place in key order.
  size_t IndexBytes() const {
    return triangles.size() * (sizeof(CatalogTriangle) + sizeof(uint64_t) + sizeof(int32_t));
  }
};

// A source catalog with proper motions (rad/yr; pm_ra is mu_alpha * cos(dec)).
struct SourceStar {
  CatalogStar star;
  double pm_ra_rad_per_yr = 0, pm_dec_rad_per_yr = 0;
};
struct SourceCatalog {
  std::string source;
  std::string kind;  // "xplanet_bsc", "bsc5", "kstars"
  bool has_proper_motion = false;
  std::vector<SourceStar> stars;
};

// Binary BSC5 (SAO TDC format: 28-byte header, 32-byte entries, J2000, proper motion rad/yr).
SourceCatalog LoadBsc5(const std::string& path);
// KStars stars.dat (fixed-width text: RA hhmmss.ss, Dec sddmmss.s, pmRA, pmDec in mas/yr, plx, mag).
// star_id = 1000000 + data-row ordinal (see the header comment).
SourceCatalog LoadKstarsStars(const std::string& path);
// Any of the three by content: xplanet BSC text, binary BSC5, KStars stars.dat.
SourceCatalog LoadSourceCatalog(const std::string& path);
// Gives KStars stars the HR number of a BSC star within `radius_arcsec` and 1 mag (J2000 positions).
void AssignHrNumbers(SourceCatalog* kstars, const StarCatalog& bsc, double radius_arcsec = 30.0);

// The default source for a FOV: xplanet BSC when its magnitude range suffices, else KStars'
// stars.dat when installed. $SSIU_CATALOG overrides.
std::string DefaultSourceFor(double fov_deg);

// Epoch propagation, magnitude limit, double merging, pattern index.
SolverCatalog BuildSolverCatalog(const SourceCatalog& source, const CatalogBuildOptions& options);
// From a plain star table already at its epoch (e.g. the simulator's catalog): no proper motion.
SolverCatalog BuildSolverCatalog(const StarCatalog& stars, const CatalogBuildOptions& options);

// DIR/stars.csv (human-readable table), DIR/catalog.bin (stars with their unit vectors, triangles with
// their features, and the search index, all as used: read back with one read and no rebuilding),
// DIR/meta.json (the parameters it was built for, and catalog.bin's size and CRC-32). Every file is written atomically
// and meta.json last, so a directory without meta.json is a build that did not finish.
void SaveSolverCatalog(const SolverCatalog& catalog, const std::string& dir);
// InputError naming the file; a damaged directory (size or checksum differing from meta.json, or no
// meta.json) is refused with the reason. catalog.bin of format 3 (before the stored index) still
// loads, its index rebuilt in memory (slower: `ssiu catalog build` anew to store it).
SolverCatalog LoadSolverCatalog(const std::string& dir);

// catalog.bin's bytes for `catalog` (what SaveSolverCatalog writes there): a flight image's blob.
std::string SolverCatalogBytes(const SolverCatalog& catalog);

// catalog.bin's bytes (in memory or ROM, e.g. a flight image) as one fixed-FOV catalog: the stars,
// triangles and stored index are read without rebuilding anything. InputError naming `name` when the
// bytes are not a whole catalog (the CRC is meta.json's; flight/ssiu_flight.h checks it).
// Without `star_tree` the stars' kd-tree is not built (the flight path's lookups use the stored sky
// cells): nothing is built that a search needs, the parts are read as stored. With `in_place` the
// tables of a format-5 blob (8-byte aligned) are searched where they lie, nothing copied: the bytes
// must then outlive the catalog and every copy of it (an older format, or an unaligned blob, is
// copied as without it).
SolverCatalog ParseSolverCatalog(const void* data, size_t bytes, const std::string& name, bool star_tree = true,
                                 bool in_place = false);

enum class CatalogDirState { kAbsent, kIncomplete, kDamaged, kOk };
const char* CatalogDirStateName(CatalogDirState s);  // "absent", "incomplete", "damaged", "ok"
inline std::ostream& operator<<(std::ostream& os, CatalogDirState v) { return os << CatalogDirStateName(v); }
// Checks a catalog directory against its meta.json without parsing it; `why` says what is wrong.
CatalogDirState CheckCatalogDir(const std::string& dir, std::string* why = nullptr);

// A built catalog serves cameras whose horizontal FOV is within this fraction of the one it was built for.
constexpr double kCatalogFovTolerance = 0.10;
// The catalog in `dir`: loaded when complete (refused when built for another FOV, see
// kCatalogFovTolerance), built there when absent or unfinished, and when damaged rebuilt
// (rebuild_damaged, the cache) or refused with the reason (a directory the user gave). Builders
// of one directory are serialised by a lock file (DIR/.lock), so concurrent runs cannot tear it.
SolverCatalog LoadOrBuildCatalogIn(const std::string& dir, const std::string& source_path,
                                   const CatalogBuildOptions& options, bool rebuild_damaged);

// The cache directory for built catalogs: $SSIU_CATALOG_DIR, else $XDG_CACHE_HOME/ssiu/catalog,
// else ~/.cache/ssiu/catalog.
std::string CatalogCacheDir();
// Loads the cached catalog for (source, fov, options) or builds and caches it.
SolverCatalog LoadOrBuildCatalog(const std::string& source_path, const CatalogBuildOptions& options);

}  // namespace ssiu
