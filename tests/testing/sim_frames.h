// Simulated frames spoiled in known ways (header-only: for tests that link the sim stage).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "sim/frame_sim.h"

namespace ssiu::testing {

// Puts a persistent hot pixel (`value` ADU) 2 px right of the brightest star at least 6 px inside the
// frame: on the star's wing, where the detector's own spike test cannot tell it from the star, so only a
// list of known hot pixels keeps it out of the centroid. Returns its [x, y].
inline std::array<int, 2> HotPixelOnTheBrightestStarsWing(SimulatedFrame* sf, uint16_t value = 30000) {
  const int w = sf->image.width, h = sf->image.height;
  const auto inside = [&](const SimStar& s) { return s.x_px > 5 && s.x_px < w - 6 && s.y_px > 5 && s.y_px < h - 6; };
  const auto brightest = std::min_element(sf->stars.begin(), sf->stars.end(), [&](const SimStar& a, const SimStar& b) {
    return inside(a) && (!inside(b) || a.mag < b.mag);
  });
  const std::array<int, 2> p = {static_cast<int>(std::lround(brightest->x_px)) + 2,
                                static_cast<int>(std::lround(brightest->y_px))};
  sf->image.at(p[0], p[1]) = value;
  return p;
}

}  // namespace ssiu::testing
