// Fixtures shared by the simulator's image tests (smear, PSF-shape and sky knobs): a hand-made
// catalog, noise-free options, and the second moments of a star's image.
#pragma once

#include <cmath>
#include <vector>

#include "core/catalog.h"
#include "core/types.h"
#include "sim/frame_sim.h"

namespace ssiu::testing {

// A catalog of stars of magnitude `mag` along the given inertial directions (ids 1, 2, ...).
inline StarCatalog Stars(const std::vector<Vec3>& units, double mag) {
  StarCatalog c;
  for (size_t k = 0; k < units.size(); ++k) {
    CatalogStar s;
    s.id = static_cast<StarId>(k + 1);
    s.mag = mag;
    s.unit = units[k].normalized();
    s.ra_rad = std::atan2(s.unit.y(), s.unit.x());
    s.dec_rad = std::asin(s.unit.z());
    c.stars.push_back(s);
  }
  return c;
}

// Noise-free, defect-free options: the image is exactly bias + background + the stars (rounded to ADU).
inline FrameSimOptions Clean() {
  FrameSimOptions o;
  o.shot_noise = false;
  o.read_noise_e = 0;
  o.hot_pixels = o.dead_pixels = o.cosmic_rays = 0;
  return o;
}

struct Moments {
  double flux_e = 0, mx = 0, my = 0;
  Mat2 cov = Mat2::Zero();
};

// Flux (e-) and second moments (px^2) of the background-subtracted image in a box around (x, y)
// (flat sky: the background of `o` without gradient or vignetting).
inline Moments ImageMoments(const SimulatedFrame& f, const FrameSimOptions& o, double x, double y, int half) {
  const double bg_adu = o.bias_adu + (o.background_e_per_s + o.dark_current_e_per_s) * o.exposure_s / o.gain_e_per_adu;
  double s = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  for (int j = static_cast<int>(y) - half; j <= static_cast<int>(y) + half; ++j) {
    for (int i = static_cast<int>(x) - half; i <= static_cast<int>(x) + half; ++i) {
      const double a = f.image.at(i, j) - bg_adu;
      s += a, sx += a * i, sy += a * j, sxx += a * i * i, syy += a * j * j, sxy += a * i * j;
    }
  }
  Moments m;
  m.flux_e = s * o.gain_e_per_adu;
  m.mx = sx / s, m.my = sy / s;
  m.cov << sxx / s - m.mx * m.mx, sxy / s - m.mx * m.my, sxy / s - m.mx * m.my, syy / s - m.my * m.my;
  return m;
}

}  // namespace ssiu::testing
