// Star catalogs as read from their sources. `star_id` is the number in the source catalog
// (HR for the Bright Star Catalogue). Issue-level features (proper motion, doubles, pattern
// index) live in identify/; this is the plain table every stage can read.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/types.h"

namespace ssiu {

using StarId = int32_t;
constexpr StarId kInvalidStarId = -1;

struct CatalogStar {
  StarId id = kInvalidStarId;
  double ra_rad = 0;
  double dec_rad = 0;
  double mag = 0;             // visual magnitude V
  Vec3 unit = Vec3::UnitX();  // unit vector (ICRS) at the catalog's epoch
  // Proper motion (rad per Julian year; pm_ra is mu_alpha * cos(dec)); 0 when the source has none.
  double pm_ra_rad_per_yr = 0, pm_dec_rad_per_yr = 0;
};

// A read-only run of catalog stars: a StarCatalog's or a SolverCatalog's table (any contiguous
// container of CatalogStar with data() and size()), for functions that only read them.
class StarSpan {
 public:
  template <typename C>
  StarSpan(const C& c) : data_(c.data()), n_(c.size()) {}  // NOLINT: implicit, as a view
  const CatalogStar* begin() const { return data_; }
  const CatalogStar* end() const { return data_ + n_; }
  size_t size() const { return n_; }
  const CatalogStar& operator[](size_t i) const { return data_[i]; }

 private:
  const CatalogStar* data_;
  size_t n_;
};

struct StarCatalog {
  std::string source;
  std::vector<CatalogStar> stars;  // sorted brightest first
  double epoch_year = 2000.0;      // Julian epoch of the positions (proper motion counts from here)
};

// Debian xplanet's Bright Star Catalogue: columns Dec(deg) RA(h) Mag "Name" HR HD SAO.
StarCatalog LoadXplanetBsc(const std::string& path, double mag_max = 99.0);
// $SSIU_BSC if set, else /usr/share/xplanet/stars/BSC.
std::string DefaultBscPath();

}  // namespace ssiu
