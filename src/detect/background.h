// Internal to detect: tiled robust background and noise with bilinear interpolation.
#pragma once

#include <cstdint>
#include <vector>

#include "core/arena.h"
#include "core/image.h"

namespace ssiu {

struct BackgroundGrid {
  explicit BackgroundGrid(std::pmr::memory_resource* mr = std::pmr::get_default_resource())
      : level(mr), sigma(mr), box_sigma(mr) {}
  int tile = 64, nx = 0, ny = 0, width = 0, height = 0;
  ScratchVec<float> level, sigma;  // per tile, row-major (ny x nx), after a 3x3 median
  // Noise of the b x b box sum (the matched filter), measured rather than assumed b * sigma: real
  // frames (demosaiced colour sensors, fixed-pattern structure) have correlated pixel noise.
  ScratchVec<float> box_sigma;
  int box_half = 1;
  double median_level = 0, median_sigma = 0;
  // The frame shows JPEG's 8x8 blocks (BlockArtefactRatio above kBlockArtefactRatio): the noise of the
  // pixels and of the box sums is then taken from their lower tails too (background.cc).
  bool block_artefacts = false;
  double block_ratio = 1;

  double LevelAt(double x, double y) const { return Interp(level, x, y); }
  double SigmaAt(double x, double y) const { return Interp(sigma, x, y); }
  // out[x] = scale * (level(x, y) + k_sigma * sigma(x, y)) for every x of row y.
  void RowLevels(int y, ScratchVec<float>* out, double k_sigma, double scale) const;
  // box^2 * level(x, y) + k * box_sigma(x, y), the detection threshold of the box sum, at the ny
  // tile-centre rows (ny x width, row-major), and for image row y
  // the two centre rows and the weight between them: threshold(x, y) = (1 - ay) rows[j0][x] +
  // ay rows[j1][x] (bilinear interpolation is linear in y between centre rows), so the full-frame
  // pass needs no per-row interpolation in x.
  void BoxThresholdAtCentres(double k, ScratchVec<float>* rows) const;
  void CentreRowsOf(int y, int* j0, int* j1, float* ay) const;

 private:
  // out[x] = a * level + b * second, bilinear in the tile grid (out holds at least width values).
  void RowCombination(int y, ScratchVec<float>* out, double a, double b, const ScratchVec<float>& second) const;
  // The same at tile-grid row coordinate fy (0 = centre of the first tile row), into out[0, width).
  void RowCombinationAt(double fy, float* out, double a, double b, const ScratchVec<float>& second) const;
  double Interp(const ScratchVec<float>& v, double x, double y) const;
};

// Mean absolute difference of neighbouring pixels across the 8-pixel grid lines (x or y = 8k - 1 | 8k)
// over that within the blocks, rows and columns together: about 1 for a frame that was never
// block-coded, above it for a JPEG whose quantised DCT blocks (ITU-T T.81) left steps at their edges.
double BlockArtefactRatio(const ImageView& img);
constexpr double kBlockArtefactRatio = 1.05;

// Scratch of EstimateBackground, reserved once (Reserve) so that repeated estimates allocate nothing.
struct BackgroundScratch {
  explicit BackgroundScratch(std::pmr::memory_resource* mr = std::pmr::get_default_resource())
      : samples(mr), box_samples(mr), select(mr), hist(mr), grid(mr) {}
  ScratchVec<int32_t> samples, box_samples, select, hist;
  ScratchVec<float> grid;  // a tile grid's worth
  // Capacity for images up to max_width x max_height and tiles of at least min_tile_px (or the
  // image's shorter side, when that is smaller); `out` gets its tile grids reserved too.
  void Reserve(int max_width, int max_height, int min_tile_px, BackgroundGrid* out);
};

// Median and MAD-based sigma (1.4826 MAD) of a subsample of each tile, then a 3x3 median over the
// tile grid so that a tile filled by a bright star or an extended object takes its neighbours' value.
// Also measures the noise of the (2 box_half + 1)^2 box sum at the same sample points.
BackgroundGrid EstimateBackground(const ImageView& img, int tile_px, int box_half = 1);
// The same into `out`, with the scratch given (no allocation when both were reserved for the image
// and tile size).
// block_aware: the noise of a frame with JPEG blocks from the lower tails too (BackgroundGrid::block_artefacts).
void EstimateBackground(const ImageView& img, int tile_px, int box_half, BackgroundScratch* scratch,
                        BackgroundGrid* out, bool block_aware = true);

}  // namespace ssiu
