#include "detect/background.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace ssiu {
namespace {

template <typename T>
T MedianOf(T* v, size_t n) {
  const size_t m = n / 2;
  std::nth_element(v, v + m, v + n);
  return v[m];
}
template <typename T>
T MedianOf(ScratchVec<T>& v) {
  return MedianOf(v.data(), v.size());
}

// 3x3 median over the tile grid (edges use the available neighbours), into *out (resized to g's size).
void MedianFilterGrid(const ScratchVec<float>& g, int nx, int ny, ScratchVec<float>* out) {
  out->resize(g.size());
  std::array<float, 9> nb;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      size_t n = 0;
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          const int a = i + di, b = j + dj;
          if (a >= 0 && b >= 0 && a < nx && b < ny) nb[n++] = g[b * nx + a];
        }
      }
      (*out)[j * nx + i] = MedianOf(nb.data(), n);
    }
  }
}

// Median and MAD (median absolute deviation from the median) of integer samples, exactly the
// order statistics nth_element would give (element n/2 of the sorted values and of the sorted
// deviations), found from a histogram: the samples of a tile are mostly background, so a window of
// a few noise widths around a rough median (from 16 of the samples) holds both statistics, and the
// histogram walk costs far less than two selections. When the walk reaches a window edge (a tile
// dominated by a star, a dead or saturated area) the selections are done after all.
struct MedianMad {
  int32_t median = 0, mad = 0;
};

MedianMad MedianAndMad(const ScratchVec<int32_t>& s, ScratchVec<int32_t>* scratch, ScratchVec<int32_t>* hist) {
  MedianMad out;
  const size_t n = s.size();
  const size_t m = n / 2;
  if (n >= 32) {
    std::array<int32_t, 16> probe;
    for (size_t k = 0; k < 16; ++k) probe[k] = s[k * n / 16];
    std::sort(probe.begin(), probe.end());
    const int64_t anchor = probe[8];
    const int64_t half_width = std::clamp<int64_t>(4 * int64_t(probe[12] - probe[3]) + 16, 32, 8192);
    const int64_t lo = anchor - half_width, hi = anchor + half_width;  // bins lo..hi; ends collect the rest
    hist->assign(static_cast<size_t>(hi - lo + 1), 0);
    int32_t* hb = hist->data();
    size_t below = 0;  // samples under the anchor
    for (int32_t v : s) below += v < anchor;
    for (int32_t v : s) ++hb[std::clamp<int64_t>(v, lo, hi) - lo];
    // Median: the value b with (count < b) <= m < (count <= b), walked to from the anchor.
    int64_t med = -1;
    const int64_t a = anchor - lo;
    if (below > m) {
      size_t lt = below;  // count < b for b = a
      for (int64_t b = a - 1; b >= 0; --b) {
        lt -= static_cast<size_t>(hb[b]);
        if (lt <= m) {
          med = b;
          break;
        }
      }
    } else {
      size_t le = below;
      for (int64_t b = a; b <= hi - lo; ++b) {
        le += static_cast<size_t>(hb[b]);
        if (le > m) {
          med = b;
          break;
        }
      }
    }
    if (med > 0 && med < hi - lo) {
      // MAD: the smallest d with more than m samples within med +- d.
      size_t within = static_cast<size_t>(hb[med]);
      int64_t d = 0;
      while (within <= m) {
        ++d;
        if (med - d <= 0 || med + d >= hi - lo) break;
        within += static_cast<size_t>(hb[med - d] + hb[med + d]);
      }
      if (within > m) {
        out.median = static_cast<int32_t>(med + lo);
        out.mad = static_cast<int32_t>(d);
        return out;
      }
    }
  }
  *scratch = s;
  out.median = MedianOf(*scratch);
  for (int32_t& v : *scratch) v = std::abs(v - out.median);
  out.mad = MedianOf(*scratch);
  return out;
}

// Robust sigma of integer samples: 1.4826 MAD, or for data quantised near one count (where the
// MAD is 0, 1 or 2 counts and says little) the standard deviation of the samples within
// +-5 sigma of the median.
float RobustSigma(const ScratchVec<int32_t>& s, const MedianMad& mm) {
  const float mad = static_cast<float>(mm.mad);
  const float sigma_mad = 1.4826f * mad;
  if (mad > 2) return sigma_mad;
  const double clip = 5.0 * std::max(1.0f, sigma_mad);
  double n = 0, sum = 0, sum2 = 0;
  for (int32_t v : s) {
    const double d = v - mm.median;
    if (std::abs(d) > clip) continue;
    n += 1;
    sum += d;
    sum2 += d * d;
  }
  if (n < 2) return std::max(sigma_mad, 0.5f);
  const double var = sum2 / n - (sum / n) * (sum / n);
  return std::max(static_cast<float>(std::sqrt(std::max(var, 0.0))), 0.5f);
}

// A lossy frame's noise (of the pixels and of the box sums): JPEG leaves many blocks flat (their AC
// coefficients quantised to zero) and others textured, a distribution with a narrow core and wide shoulders whose MAD understates the
// spread that reaches the threshold. Stars sit in the upper tail only, so the lower one measures the
// shoulders: (median - 10 % quantile) / 1.2816 is sigma for Gaussian noise.
float LowerTailSigma(const ScratchVec<int32_t>& s, double median, ScratchVec<int32_t>* scratch) {
  scratch->assign(s.begin(), s.end());
  const size_t k = scratch->size() / 10;
  std::nth_element(scratch->begin(), scratch->begin() + static_cast<std::ptrdiff_t>(k), scratch->end());
  return static_cast<float>(std::max(0.0, (median - (*scratch)[k]) / 1.2816));
}

}  // namespace

double BlockArtefactRatio(const ImageView& img) {
  if (img.width < 32 || img.height < 32) return 1;
  double edge = 0, inside = 0;
  int64_t n_edge = 0, n_inside = 0;
  // Every 4th row and column are enough (about N/8 edge pairs of N/2 sampled: the ratio to ~1 % on a
  // 512^2 frame) and keep the cost to half a pass over the frame.
  for (int y = 0; y + 1 < img.height; y += 4) {  // across vertical grid lines
    const uint16_t* r = img.row(y);
    for (int x = 0; x + 1 < img.width; ++x) {
      const int d = std::abs(int(r[x + 1]) - int(r[x]));
      if ((x & 7) == 7) {
        edge += d, ++n_edge;
      } else {
        inside += d, ++n_inside;
      }
    }
  }
  for (int y = 0; y + 1 < img.height; ++y) {  // across horizontal grid lines
    const uint16_t *r0 = img.row(y), *r1 = img.row(y + 1);
    const bool at_edge = (y & 7) == 7;
    double sum = 0;
    int64_t n = 0;
    for (int x = 0; x < img.width; x += 4, ++n) sum += std::abs(int(r1[x]) - int(r0[x]));
    (at_edge ? edge : inside) += sum;
    (at_edge ? n_edge : n_inside) += n;
  }
  if (n_edge == 0 || n_inside == 0 || inside <= 0) return 1;
  return (edge / n_edge) / (inside / n_inside);
}

namespace {
// Samples of one tile: about 256 (step = tile / 16), at most 31 per row and column (tiles under 32 px
// take every pixel), plus the one a tile without samples takes.
constexpr size_t kMaxTileSamples = 31 * 31 + 1;
// Histogram bins of MedianAndMad: 2 x its largest half-width + 1.
constexpr size_t kMaxHistBins = 2 * 8192 + 1;
}  // namespace

void BackgroundScratch::Reserve(int max_width, int max_height, int min_tile_px, BackgroundGrid* out) {
  // The tile is min(tile_px, shorter side), so at least min(min_tile_px, 16) on a frame of >= 16 px.
  const int t = std::max(1, std::min(min_tile_px, 16));
  const size_t tiles = static_cast<size_t>((max_width + t - 1) / t) * ((max_height + t - 1) / t);
  samples.reserve(kMaxTileSamples);
  box_samples.reserve(kMaxTileSamples);
  select.reserve(kMaxTileSamples);
  hist.reserve(kMaxHistBins);
  grid.reserve(tiles);
  out->level.reserve(tiles);
  out->sigma.reserve(tiles);
  out->box_sigma.reserve(tiles);
}

BackgroundGrid EstimateBackground(const ImageView& img, int tile_px, int box_half) {
  BackgroundScratch scratch;
  BackgroundGrid g;
  EstimateBackground(img, tile_px, box_half, &scratch, &g);
  return g;
}

void EstimateBackground(const ImageView& img, int tile_px, int box_half, BackgroundScratch* sc,
                        BackgroundGrid* out, bool block_aware) {
  BackgroundGrid& g = *out;
  g.width = img.width;
  g.height = img.height;
  g.tile = std::min(tile_px, std::min(img.width, img.height));
  g.nx = (img.width + g.tile - 1) / g.tile;
  g.ny = (img.height + g.tile - 1) / g.tile;
  g.level.resize(static_cast<size_t>(g.nx) * g.ny);
  g.sigma.resize(g.level.size());
  g.box_sigma.resize(g.level.size());
  g.box_half = box_half;
  g.block_ratio = block_aware ? BlockArtefactRatio(img) : 1.0;
  g.block_artefacts = g.block_ratio > kBlockArtefactRatio;  // never without block_aware (ratio 1)
  const int hb = box_half;
  // Subsample about 256 pixels of each tile (median to ~0.08 sigma; the 3x3 grid median then
  // averages neighbouring tiles).
  const int step = std::max(1, static_cast<int>(std::sqrt(double(g.tile) * g.tile / 256.0)));
  ScratchVec<int32_t>&s = sc->samples, &bs = sc->box_samples, &scratch = sc->select, &hist = sc->hist;
  for (int ty = 0; ty < g.ny; ++ty) {
    for (int tx = 0; tx < g.nx; ++tx) {
      const int x0 = tx * g.tile, y0 = ty * g.tile;
      const int x1 = std::min(img.width, x0 + g.tile), y1 = std::min(img.height, y0 + g.tile);
      s.clear();
      bs.clear();
      for (int y = y0 + step / 2; y < y1; y += step) {
        const uint16_t* r = img.row(y);
        const bool box_row = y >= hb && y < img.height - hb;
        for (int x = x0 + ((y / step) & 1 ? step / 2 : 0); x < x1; x += step) {
          s.push_back(r[x]);
          // Box sums at every other sample: enough for their noise, at half the cost.
          if (!box_row || x < hb || x >= img.width - hb || (s.size() & 1)) continue;
          int32_t sum = 0;
          if (hb == 1) {  // the common 3x3 case, unrolled
            const uint16_t *a = img.row(y - 1) + x, *b = r + x, *c = img.row(y + 1) + x;
            sum = a[-1] + a[0] + a[1] + b[-1] + b[0] + b[1] + c[-1] + c[0] + c[1];
          } else {
            for (int dy = -hb; dy <= hb; ++dy) {
              const uint16_t* rr = img.row(y + dy);
              for (int dx = -hb; dx <= hb; ++dx) sum += rr[x + dx];
            }
          }
          bs.push_back(sum);
        }
      }
      if (s.empty()) s.push_back(img.at(x0, y0));
      const MedianMad mm = MedianAndMad(s, &scratch, &hist);
      float sig = RobustSigma(s, mm);
      if (g.block_artefacts && s.size() >= 16) sig = std::max(sig, LowerTailSigma(s, mm.median, &scratch));
      g.level[ty * g.nx + tx] = static_cast<float>(mm.median);
      g.sigma[ty * g.nx + tx] = sig;
      const int nbox = (2 * hb + 1);
      float box_sig = static_cast<float>(nbox) * sig;
      if (bs.size() >= 16) {
        const MedianMad bm = MedianAndMad(bs, &scratch, &hist);
        box_sig = std::max(RobustSigma(bs, bm), 0.5f * box_sig);
        if (g.block_artefacts) box_sig = std::max(box_sig, LowerTailSigma(bs, bm.median, &scratch));
      }
      g.box_sigma[ty * g.nx + tx] = box_sig;
    }
  }
  ScratchVec<float>& tmp = sc->grid;
  for (ScratchVec<float>* v : {&g.level, &g.sigma, &g.box_sigma}) {
    MedianFilterGrid(*v, g.nx, g.ny, &tmp);
    v->swap(tmp);  // both hold a grid's capacity
  }
  tmp.assign(g.level.begin(), g.level.end());
  g.median_level = MedianOf(tmp);
  tmp.assign(g.sigma.begin(), g.sigma.end());
  g.median_sigma = MedianOf(tmp);
}

double BackgroundGrid::Interp(const ScratchVec<float>& v, double x, double y) const {
  // Tile centres sit at (i + 0.5) * tile - 0.5; clamp outside the outermost centres.
  const double fx = std::clamp((x + 0.5) / tile - 0.5, 0.0, nx - 1.0);
  const double fy = std::clamp((y + 0.5) / tile - 0.5, 0.0, ny - 1.0);
  const int i0 = std::min(static_cast<int>(fx), nx - 1), j0 = std::min(static_cast<int>(fy), ny - 1);
  const int i1 = std::min(i0 + 1, nx - 1), j1 = std::min(j0 + 1, ny - 1);
  const double ax = fx - i0, ay = fy - j0;
  const double top = v[j0 * nx + i0] * (1 - ax) + v[j0 * nx + i1] * ax;
  const double bot = v[j1 * nx + i0] * (1 - ax) + v[j1 * nx + i1] * ax;
  return top * (1 - ay) + bot * ay;
}

void BackgroundGrid::RowLevels(int y, ScratchVec<float>* out, double k_sigma, double scale) const {
  RowCombination(y, out, scale, k_sigma * scale, sigma);
}

void BackgroundGrid::BoxThresholdAtCentres(double k, ScratchVec<float>* rows) const {
  const double nbox = 2 * box_half + 1;
  rows->resize(static_cast<size_t>(ny) * width);
  for (int j = 0; j < ny; ++j)
    RowCombinationAt(j, rows->data() + static_cast<size_t>(j) * width, nbox * nbox, k, box_sigma);
}

void BackgroundGrid::CentreRowsOf(int y, int* j0, int* j1, float* ay) const {
  const double fy = std::clamp((y + 0.5) / tile - 0.5, 0.0, ny - 1.0);
  *j0 = std::min(static_cast<int>(fy), ny - 1);
  *j1 = std::min(*j0 + 1, ny - 1);
  *ay = static_cast<float>(fy - *j0);
}

void BackgroundGrid::RowCombination(int y, ScratchVec<float>* out, double a, double b,
                                    const ScratchVec<float>& second) const {
  RowCombinationAt((y + 0.5) / tile - 0.5, out->data(), a, b, second);
}

void BackgroundGrid::RowCombinationAt(double fy_in, float* o, double a, double b,
                                      const ScratchVec<float>& second) const {
  const double fy = std::clamp(fy_in, 0.0, ny - 1.0);
  const int j0 = std::min(static_cast<int>(fy), ny - 1), j1 = std::min(j0 + 1, ny - 1);
  const double ay = fy - j0;
  // Value at tile column i for this row (computed where needed: no per-row buffer), then linear
  // along the row.
  auto col = [&](int i) {
    const double l = level[j0 * nx + i] * (1 - ay) + level[j1 * nx + i] * ay;
    const double s = second[j0 * nx + i] * (1 - ay) + second[j1 * nx + i] * ay;
    return a * l + b * s;
  };
  // Linear between tile centres, constant beyond the outermost ones: segment by segment so the
  // inner loop is a plain multiply-add.
  for (int x = 0; x < width;) {
    const double fx = (x + 0.5) / tile - 0.5;
    if (fx <= 0 || nx == 1) {
      const int xe = std::max(x + 1, nx == 1 ? width : std::min(width, tile / 2));
      const float c0 = static_cast<float>(col(0));
      for (; x < xe; ++x) o[x] = c0;
      continue;
    }
    const int i0 = static_cast<int>(fx);
    if (i0 >= nx - 1) {
      const float c1 = static_cast<float>(col(nx - 1));
      for (; x < width; ++x) o[x] = c1;
      break;
    }
    const int xe = std::min(width, (i0 + 1) * tile + tile / 2);  // next centre (exclusive)
    const double c0 = col(i0), c1 = col(i0 + 1);
    const float slope = static_cast<float>((c1 - c0) / tile);
    const float base = static_cast<float>(c0 + (x - ((i0 + 0.5) * tile - 0.5)) * slope);
    for (int k = 0; x < xe; ++x, ++k) o[x] = base + k * slope;
  }
}

}  // namespace ssiu
