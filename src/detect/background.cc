#include "detect/background.h"

#include <algorithm>
#include <cmath>

namespace ssiu {
namespace {

template <typename T>
T MedianOf(std::vector<T>& v) {
  const size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + m, v.end());
  return v[m];
}

// 3x3 median over the tile grid (edges use the available neighbours).
std::vector<float> MedianFilterGrid(const std::vector<float>& g, int nx, int ny) {
  std::vector<float> out(g.size()), nb;
  nb.reserve(9);
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      nb.clear();
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          const int a = i + di, b = j + dj;
          if (a >= 0 && b >= 0 && a < nx && b < ny) nb.push_back(g[b * nx + a]);
        }
      }
      out[j * nx + i] = MedianOf(nb);
    }
  }
  return out;
}

// Robust sigma of integer samples: 1.4826 MAD, or for data quantised near one count (where the
// MAD is 0, 1 or 2 counts and says little) the standard deviation of the samples within
// +-5 sigma of the median.
float RobustSigma(std::vector<int32_t>& s, int32_t med, std::vector<int32_t>& dev) {
  dev.resize(s.size());
  for (size_t k = 0; k < s.size(); ++k) dev[k] = std::abs(s[k] - med);
  const float mad = static_cast<float>(MedianOf(dev));
  const float sigma_mad = 1.4826f * mad;
  if (mad > 2) return sigma_mad;
  const double clip = 5.0 * std::max(1.0f, sigma_mad);
  double n = 0, sum = 0, sum2 = 0;
  for (int32_t v : s) {
    const double d = v - med;
    if (std::abs(d) > clip) continue;
    n += 1;
    sum += d;
    sum2 += d * d;
  }
  if (n < 2) return std::max(sigma_mad, 0.5f);
  const double var = sum2 / n - (sum / n) * (sum / n);
  return std::max(static_cast<float>(std::sqrt(std::max(var, 0.0))), 0.5f);
}

}  // namespace

BackgroundGrid EstimateBackground(const ImageView& img, int tile_px, int box_half) {
  BackgroundGrid g;
  g.width = img.width;
  g.height = img.height;
  g.tile = std::min(tile_px, std::min(img.width, img.height));
  g.nx = (img.width + g.tile - 1) / g.tile;
  g.ny = (img.height + g.tile - 1) / g.tile;
  g.level.resize(static_cast<size_t>(g.nx) * g.ny);
  g.sigma.resize(g.level.size());
  g.box_sigma.resize(g.level.size());
  g.box_half = box_half;
  const int hb = box_half;
  // Subsample about 256 pixels of each tile (median to ~0.08 sigma; the 3x3 grid median then
  // averages neighbouring tiles).
  const int step = std::max(1, static_cast<int>(std::sqrt(double(g.tile) * g.tile / 256.0)));
  std::vector<int32_t> s, dev, bs;
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
            const uint16_t *a = img.row(y - 1) + x, *b = img.row(y) + x, *c = img.row(y + 1) + x;
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
      const int32_t med = MedianOf(s);
      const float sig = RobustSigma(s, med, dev);
      g.level[ty * g.nx + tx] = static_cast<float>(med);
      g.sigma[ty * g.nx + tx] = sig;
      const int nbox = (2 * hb + 1);
      float box_sig = static_cast<float>(nbox) * sig;
      if (bs.size() >= 16) {
        const int32_t bmed = MedianOf(bs);
        box_sig = std::max(RobustSigma(bs, bmed, dev), 0.5f * box_sig);
      }
      g.box_sigma[ty * g.nx + tx] = box_sig;
    }
  }
  g.level = MedianFilterGrid(g.level, g.nx, g.ny);
  g.sigma = MedianFilterGrid(g.sigma, g.nx, g.ny);
  g.box_sigma = MedianFilterGrid(g.box_sigma, g.nx, g.ny);
  std::vector<float> tmp = g.level;
  g.median_level = MedianOf(tmp);
  tmp = g.sigma;
  g.median_sigma = MedianOf(tmp);
  return g;
}

double BackgroundGrid::Interp(const std::vector<float>& v, double x, double y) const {
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

void BackgroundGrid::RowLevels(int y, std::vector<float>* out, double k_sigma, double scale) const {
  RowCombination(y, out, scale, k_sigma * scale, sigma);
}

void BackgroundGrid::RowBoxThreshold(int y, std::vector<float>* out, double k) const {
  const double nbox = 2 * box_half + 1;
  RowCombination(y, out, nbox * nbox, k, box_sigma);
}

void BackgroundGrid::RowCombination(int y, std::vector<float>* out, double a, double b,
                                    const std::vector<float>& second) const {
  const double fy = std::clamp((y + 0.5) / tile - 0.5, 0.0, ny - 1.0);
  const int j0 = std::min(static_cast<int>(fy), ny - 1), j1 = std::min(j0 + 1, ny - 1);
  const double ay = fy - j0;
  // Value at each tile column for this row, then linear along the row.
  std::vector<double> col(nx);
  for (int i = 0; i < nx; ++i) {
    const double l = level[j0 * nx + i] * (1 - ay) + level[j1 * nx + i] * ay;
    const double s = second[j0 * nx + i] * (1 - ay) + second[j1 * nx + i] * ay;
    col[i] = a * l + b * s;
  }
  // Linear between tile centres, constant beyond the outermost ones: segment by segment so the
  // inner loop is a plain multiply-add.
  float* o = out->data();
  for (int x = 0; x < width;) {
    const double fx = (x + 0.5) / tile - 0.5;
    if (fx <= 0 || nx == 1) {
      const int xe = std::max(x + 1, nx == 1 ? width : std::min(width, tile / 2));
      for (; x < xe; ++x) o[x] = static_cast<float>(col[0]);
      continue;
    }
    const int i0 = static_cast<int>(fx);
    if (i0 >= nx - 1) {
      for (; x < width; ++x) o[x] = static_cast<float>(col[nx - 1]);
      break;
    }
    const int xe = std::min(width, (i0 + 1) * tile + tile / 2);  // next centre (exclusive)
    const float slope = static_cast<float>((col[i0 + 1] - col[i0]) / tile);
    const float base = static_cast<float>(col[i0] + (x - ((i0 + 0.5) * tile - 0.5)) * slope);
    for (int k = 0; x < xe; ++x, ++k) o[x] = base + k * slope;
  }
}

}  // namespace ssiu
