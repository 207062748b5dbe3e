// Internal to detect: tiled robust background and noise with bilinear interpolation.
#pragma once

#include <vector>

#include "core/image.h"

namespace ssiu {

struct BackgroundGrid {
  int tile = 64, nx = 0, ny = 0, width = 0, height = 0;
  std::vector<float> level, sigma;  // per tile, row-major (ny x nx), after a 3x3 median
  double median_level = 0, median_sigma = 0;

  double LevelAt(double x, double y) const { return Interp(level, x, y); }
  double SigmaAt(double x, double y) const { return Interp(sigma, x, y); }
  // out[x] = scale * (level(x, y) + k_sigma * sigma(x, y)) for every x of row y.
  void RowLevels(int y, std::vector<float>* out, double k_sigma, double scale) const;

 private:
  double Interp(const std::vector<float>& v, double x, double y) const;
};

// Median and MAD-based sigma (1.4826 MAD) of a subsample of each tile, then a 3x3 median over the
// tile grid so that a tile filled by a bright star or an extended object takes its neighbours' value.
BackgroundGrid EstimateBackground(const ImageView& img, int tile_px);

}  // namespace ssiu
