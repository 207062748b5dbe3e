// Internal: a hash grid over unit vectors for "stars within an angle" queries while building
// (incremental inserts, which a static kd-tree does not allow).
#pragma once

#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "core/types.h"

namespace ssiu::internal {

class SkyGrid {
 public:
  // cell_rad: about the query radius (angle).
  explicit SkyGrid(double cell_rad) : cell_(2 * std::sin(cell_rad / 2)) {}

  void Insert(int id, const Vec3& u) { cells_[Key(Cell(u[0]), Cell(u[1]), Cell(u[2]))].push_back({id, u}); }

  // Calls fn(id, unit) for every inserted point within angle radius_rad (<= the cell size) of u.
  template <typename Fn>
  void ForEachWithin(const Vec3& u, double radius_rad, Fn&& fn) const {
    const double cos_r = std::cos(radius_rad);
    const int cx = Cell(u[0]), cy = Cell(u[1]), cz = Cell(u[2]);
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          auto it = cells_.find(Key(cx + dx, cy + dy, cz + dz));
          if (it == cells_.end()) continue;
          for (const auto& e : it->second)
            if (e.u.dot(u) >= cos_r) fn(e.id, e.u);
        }
  }

 private:
  struct Entry {
    int id;
    Vec3 u;
  };
  int Cell(double c) const { return static_cast<int>(std::floor(c / cell_)); }
  // 21 bits per signed cell index (unique for |index| < 2^20), packed without shifting negatives.
  static int64_t Key(int x, int y, int z) {
    const uint64_t m = 0x1FFFFF;
    return static_cast<int64_t>(((static_cast<uint64_t>(static_cast<uint32_t>(x)) & m) << 42) |
                                ((static_cast<uint64_t>(static_cast<uint32_t>(y)) & m) << 21) |
                                (static_cast<uint64_t>(static_cast<uint32_t>(z)) & m));
  }
  double cell_;
  std::unordered_map<int64_t, std::vector<Entry>> cells_;
};

}  // namespace ssiu::internal
