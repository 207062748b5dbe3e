#include "detect/detect.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numeric>
#include <stdexcept>

#include "core/error.h"
#include "core/stats.h"
#include "detect/background.h"
#include "detect/psf_fit.h"
#include "detect/row_kernels.h"

namespace ssiu {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

// A horizontal run of above-threshold pixels [x0, x1] in row y, and its blob label.
struct Run {
  int y, x0, x1;
  int label;
};

int FindRoot(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

struct Blob {
  int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
  int npix = 0;
  int peak_x = 0, peak_y = 0;  // brightest pixel of the filtered image inside the blob
  int64_t peak_score = INT64_MIN;
  std::vector<int> runs;
};

// sqrt of the ratio of the principal second moments of a blob's pixels (1 round, large thin).
double BlobElongation(const Blob& b, const std::vector<Run>& runs) {
  double n = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  for (int ri : b.runs) {
    const Run& r = runs[ri];
    for (int x = r.x0; x <= r.x1; ++x) {
      n += 1;
      sx += x;
      sy += r.y;
      sxx += double(x) * x;
      syy += double(r.y) * r.y;
      sxy += double(x) * r.y;
    }
  }
  if (n < 3) return 1.0;
  const double mx = sx / n, my = sy / n;
  const double cxx = sxx / n - mx * mx + 1.0 / 12, cyy = syy / n - my * my + 1.0 / 12, cxy = sxy / n - mx * my;
  const double tr = 0.5 * (cxx + cyy), det = cxx * cyy - cxy * cxy;
  const double disc = std::sqrt(std::max(tr * tr - det, 0.0));
  return std::sqrt((tr + disc) / std::max(tr - disc, 1e-3));
}

// Expected ratio of the diagonal neighbours to the peak pixel for a pixel-centred Gaussian of
// sigma s: the smallest neighbour ratio of a real star (used to call a spike sharper than the PSF).
double DiagonalRatio(double s) {
  const double k = 1.0 / (std::sqrt(2.0) * s);
  const double f0 = std::erf(0.5 * k);
  const double f1 = 0.5 * (std::erf(1.5 * k) - std::erf(0.5 * k));
  const double r = f1 / f0;
  return r * r;
}

// One bit per pixel (128 kB for a megapixel, not a megabyte to clear and fault in): the pixels every
// fit leaves out (defect-map pixels, dead pixels, single-pixel spikes).
class PixelMask {
 public:
  PixelMask(int w, int h) : w_(w), bits_((static_cast<size_t>(w) * h + 63) / 64, 0) {}
  void Set(int x, int y) {
    const size_t i = static_cast<size_t>(y) * w_ + x;
    bits_[i >> 6] |= uint64_t{1} << (i & 63);
  }
  bool Get(int x, int y) const {
    const size_t i = static_cast<size_t>(y) * w_ + x;
    return ((bits_[i >> 6] >> (i & 63)) & 1) != 0;
  }

 private:
  int w_;
  std::vector<uint64_t> bits_;
};

// A local maximum of the 3x3-summed image inside a blob.
struct Peak {
  int x, y;      // brightest raw pixel at the peak
  double score;  // 3x3 sum above background
  size_t blob;
  double nearest_px = 1e9;  // distance to the nearest other peak of the blob
};

// Peaks stored blob by blob: those of blob b are peaks[first[b] .. first[b + 1]).
struct BlobPeaks {
  std::vector<Peak> peaks;
  std::vector<size_t> first;
};

// A peak with its PSF fit and the figures the classification needs.
struct Candidate {
  size_t peak;
  PsfFit fit;
  double peak_above = 0, min_dir_ratio = 1;
  int nsat = 0;
  double smear_px = 0;  // predicted smear length at this peak (0 without a motion model)
};

// Step 0: defect-map pixels repaired (median of good neighbours) in a working copy so that they
// make no detections and do not bias the background; the fit leaves them out.
ImageView RepairDefects(const ImageView& view, const DefectMap& defects, std::vector<uint16_t>* repaired) {
  const int w = view.width, h = view.height;
  repaired->resize(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y) std::copy(view.row(y), view.row(y) + w, &(*repaired)[static_cast<size_t>(y) * w]);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (!defects.at(x, y)) continue;
      std::array<uint16_t, 8> nb;
      int n = 0;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if ((dx || dy) && xx >= 0 && yy >= 0 && xx < w && yy < h && !defects.at(xx, yy)) nb[n++] = view.at(xx, yy);
        }
      }
      if (n > 0) {
        std::nth_element(nb.begin(), nb.begin() + n / 2, nb.begin() + n);
        (*repaired)[static_cast<size_t>(y) * w + x] = nb[n / 2];
      }
    }
  }
  return ImageView{w, h, w, repaired->data()};
}

// Step 2: the box sum (2 half + 1 square, the matched filter) thresholded on its own measured local
// noise, as runs of pixels above it; and the dead pixels (raw pixels far below their background;
// `view` is the raw frame, `img` the repaired one).
void ThresholdRuns(const ImageView& img, const ImageView& view, const BackgroundGrid& bg, const DetectOptions& opt,
                   int half, const DefectMap* defects, std::vector<Run>* runs,
                   std::vector<std::pair<int, int>>* dead_pixels) {
  const int w = img.width, h = img.height, box = 2 * half + 1;
  // A row whose minimum is above the highest "dead" level of any tile needs no per-pixel test.
  double dead_level_max = -1e300;
  for (size_t k = 0; k < bg.level.size(); ++k) {
    dead_level_max = std::max(dead_level_max, double(bg.level[k]) - opt.dead_sigma * bg.sigma[k]);
  }
  std::vector<int32_t> colsum(static_cast<size_t>(w), 0);
  std::vector<float> low_row(static_cast<size_t>(w)), thr_centres;
  std::vector<uint8_t> above(static_cast<size_t>(w) + 1, 0);
  bg.BoxThresholdAtCentres(opt.threshold_sigma, &thr_centres);
  // Column sums of rows 0 .. box-1: the box rows of the first centre row, HALF.
  for (int y = 0; y < box; ++y) {
    const uint16_t* r = img.row(y);
    for (int x = 0; x < w; ++x) colsum[x] += r[x];
  }
  int32_t* cs = colsum.data();
  uint8_t* ab = above.data();
  for (int yc = 0; yc < h; ++yc) {
    const uint16_t* raw = view.row(yc);
    if (RowMin(raw, w) < dead_level_max) {
      bg.RowLevels(yc, &low_row, -opt.dead_sigma, 1.0);
      for (int x = 0; x < w; ++x) {
        if (raw[x] < low_row[x] && !(defects && defects->at(x, yc))) dead_pixels->emplace_back(x, yc);
      }
    }
    if (yc < half || yc >= h - half) continue;
    // cs holds the column sums of rows yc-half .. yc+half: box sum and threshold test in one pass.
    int j0 = 0, j1 = 0;
    float ay = 0;
    bg.CentreRowsOf(yc, &j0, &j1, &ay);
    if (BoxAboveThreshold(cs, &thr_centres[static_cast<size_t>(j0) * w], &thr_centres[static_cast<size_t>(j1) * w], ay,
                          half, w, ab)) {
      int x = half;
      while (x < w - half) {
        const void* hit = std::memchr(&ab[x], 1, static_cast<size_t>(w - half - x));
        if (!hit) break;
        x = static_cast<int>(static_cast<const uint8_t*>(hit) - ab);
        const int xs = x;
        while (x < w - half && ab[x]) ++x;
        runs->push_back({yc, xs, x - 1, -1});
      }
    }
    // Slide the column sums down one row.
    if (yc + half + 1 < h) SlideColumnSums(cs, img.row(yc + half + 1), img.row(yc - half), w);
  }
}

// Step 3: connected blobs of runs (8-connectivity), union-find over runs of adjacent rows.
std::vector<Blob> ConnectBlobs(const std::vector<Run>& runs) {
  std::vector<int> parent(runs.size());
  std::iota(parent.begin(), parent.end(), 0);
  size_t prev_begin = 0, prev_end = 0, i = 0;
  while (i < runs.size()) {
    const int y = runs[i].y;
    size_t j = i;
    while (j < runs.size() && runs[j].y == y) ++j;
    if (prev_end > prev_begin && runs[prev_begin].y == y - 1) {
      size_t p = prev_begin;
      for (size_t k = i; k < j; ++k) {
        while (p < prev_end && runs[p].x1 < runs[k].x0 - 1) ++p;
        for (size_t q = p; q < prev_end && runs[q].x0 <= runs[k].x1 + 1; ++q) {
          const int a = FindRoot(parent, static_cast<int>(k)), b = FindRoot(parent, static_cast<int>(q));
          if (a != b) parent[std::max(a, b)] = std::min(a, b);
        }
      }
    }
    prev_begin = i;
    prev_end = j;
    i = j;
  }
  std::vector<Blob> blobs;
  std::vector<int> blob_of(runs.size(), -1);
  for (size_t k = 0; k < runs.size(); ++k) {
    const int root = FindRoot(parent, static_cast<int>(k));
    if (blob_of[root] < 0) {
      blob_of[root] = static_cast<int>(blobs.size());
      blobs.emplace_back();
    }
    Blob& b = blobs[blob_of[root]];
    const Run& r = runs[k];
    b.runs.push_back(static_cast<int>(k));
    b.x0 = std::min(b.x0, r.x0);
    b.x1 = std::max(b.x1, r.x1);
    b.y0 = std::min(b.y0, r.y);
    b.y1 = std::max(b.y1, r.y);
    b.npix += r.x1 - r.x0 + 1;
  }
  return blobs;
}

// 3x3 sums of the image over a blob's bounding box plus a one-pixel margin (edge pixels
// replicated), computed once per blob from horizontal 3-sums: the peak search reads each sum about
// ten times.
struct ScoreGrid {
  int x0 = 0, y0 = 0, gw = 0, gh = 0;
  std::vector<int32_t> v, hs;
  int32_t at(int x, int y) const { return v[static_cast<size_t>(y - y0) * gw + (x - x0)]; }
  void Fill(const ImageView& img, const Blob& b) {
    const int w = img.width, h = img.height;
    x0 = b.x0 - 1;
    y0 = b.y0 - 1;
    gw = b.x1 - b.x0 + 3;
    gh = b.y1 - b.y0 + 3;
    hs.resize(static_cast<size_t>(gw) * (gh + 2));
    v.resize(static_cast<size_t>(gw) * gh);
    for (int r = 0; r < gh + 2; ++r) {
      const uint16_t* row = img.row(std::clamp(y0 - 1 + r, 0, h - 1));
      int32_t* o = &hs[static_cast<size_t>(r) * gw];
      for (int c = 0; c < gw; ++c) {
        const int x = std::clamp(x0 + c, 0, w - 1);
        o[c] = row[std::max(x - 1, 0)] + row[x] + row[std::min(x + 1, w - 1)];
      }
    }
    for (int r = 0; r < gh; ++r) {
      const int32_t* a = &hs[static_cast<size_t>(r) * gw];
      int32_t* o = &v[static_cast<size_t>(r) * gw];
      for (int c = 0; c < gw; ++c) o[c] = a[c] + a[c + gw] + a[c + 2 * gw];
    }
  }
};

// The local maxima of the 3x3 sum over the blob's pixels, brightest first.
std::vector<Peak> LocalMaxima(const ScoreGrid& grid, const std::vector<Run>& runs, const Blob& b, double level9,
                              size_t bi) {
  std::vector<Peak> local;
  for (int ri : b.runs) {
    const Run& r = runs[ri];
    for (int x = r.x0; x <= r.x1; ++x) {
      const int32_t c = grid.at(x, r.y);
      bool is_max = true;
      for (int dy = -1; dy <= 1 && is_max; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          if (!(dx || dy)) continue;
          const int32_t o = grid.at(x + dx, r.y + dy);
          // Ties broken by position so that a flat top yields one maximum.
          if (o > c || (o == c && (dy < 0 || (dy == 0 && dx < 0)))) {
            is_max = false;
            break;
          }
        }
      }
      if (is_max) local.push_back({x, r.y, c - level9, bi});
    }
  }
  std::sort(local.begin(), local.end(), [](const Peak& p, const Peak& q) { return p.score > q.score; });
  return local;
}

// Step 4: peaks, the local maxima of the 3x3-summed image inside each blob, kept when a real dip
// separates them from every brighter peak (so a star beside another star or a hot pixel is not
// lost), each moved to the brightest raw pixel next to it.
BlobPeaks FindPeaks(const ImageView& img, const BackgroundGrid& bg, std::vector<Blob>& blobs,
                    const std::vector<Run>& runs) {
  const int w = img.width, h = img.height;
  constexpr size_t kMaxPeaksPerBlob = 12;
  ScoreGrid grid;
  BlobPeaks out;
  out.first.assign(blobs.size() + 1, 0);
  for (size_t bi = 0; bi < blobs.size(); ++bi) {
    out.first[bi] = out.peaks.size();
    Blob& b = blobs[bi];
    grid.Fill(img, b);
    // Peak of the raw image inside the blob (3x3-smoothed score to be robust to noise).
    for (int ri : b.runs) {
      const Run& r = runs[ri];
      for (int x = r.x0; x <= r.x1; ++x) {
        const int64_t sc = int64_t(grid.at(x, r.y)) * 16 + img.at(x, r.y);  // tie-break on the centre pixel
        if (sc > b.peak_score) {
          b.peak_score = sc;
          b.peak_x = x;
          b.peak_y = r.y;
        }
      }
    }
    const double level9 = 9 * bg.LevelAt(b.peak_x, b.peak_y), sigma_s = 3 * bg.SigmaAt(b.peak_x, b.peak_y);
    std::vector<Peak> kept;
    for (const Peak& m : LocalMaxima(grid, runs, b, level9, bi)) {
      bool separate = true;
      double nearest = 1e9;
      for (const Peak& a : kept) {
        const double d = std::hypot(m.x - a.x, m.y - a.y);
        const int steps = std::max(2, static_cast<int>(std::ceil(2 * d)));
        double lowest = m.score;
        for (int k = 1; k < steps; ++k) {
          const int xx = static_cast<int>(std::lround(m.x + (a.x - m.x) * double(k) / steps));
          const int yy = static_cast<int>(std::lround(m.y + (a.y - m.y) * double(k) / steps));
          lowest = std::min(lowest, grid.at(xx, yy) - level9);
        }
        if (m.score - lowest < std::max(4 * sigma_s, 0.1 * m.score)) {
          separate = false;
          break;
        }
        nearest = std::min(nearest, d);
      }
      if (!separate) continue;
      Peak p = m;
      p.nearest_px = nearest;
      for (Peak& a : kept) {
        a.nearest_px = std::min(a.nearest_px, std::hypot(m.x - a.x, m.y - a.y));
      }
      kept.push_back(p);
      if (kept.size() >= kMaxPeaksPerBlob) break;
    }
    for (Peak& p : kept) {
      // Move to the brightest raw pixel next to the summed maximum.
      int mx = p.x, my = p.y;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = p.x + dx, yy = p.y + dy;
          if (xx >= 0 && yy >= 0 && xx < w && yy < h && img.at(xx, yy) > img.at(mx, my)) {
            mx = xx;
            my = yy;
          }
        }
      }
      p.x = mx;
      p.y = my;
      out.peaks.push_back(p);
    }
  }
  out.first[blobs.size()] = out.peaks.size();
  return out;
}

// Per-peak figures of step 5a.
struct PeakShape {
  std::vector<bool> is_spike;
  std::vector<double> dir_ratio, peak_above;
};

// Step 5a: single-pixel spikes found first (and masked), so that the fits of stars beside them
// leave them out. A hot pixel on top of a source is masked and the peak moved off it.
PeakShape ClassifySpikes(const ImageView& img, const BackgroundGrid& bg, const DetectOptions& opt, BlobPeaks* bp,
                         PixelMask* bad, std::vector<Rejection>* rejected) {
  const int w = img.width, h = img.height;
  const double sat = opt.saturation_adu;
  std::vector<Peak>& peaks = bp->peaks;
  PeakShape ps;
  ps.is_spike.assign(peaks.size(), false);
  ps.dir_ratio.assign(peaks.size(), 1.0);
  ps.peak_above.assign(peaks.size(), 0.0);
  for (size_t pi = 0; pi < peaks.size(); ++pi) {
    Peak& pk = peaks[pi];
    const double level = bg.LevelAt(pk.x, pk.y), sigma_n = bg.SigmaAt(pk.x, pk.y);
    auto nb = [&](int x, int y) { return img.at(std::clamp(x, 0, w - 1), std::clamp(y, 0, h - 1)) - level; };
    // A hot pixel (or a one-pixel hit) on top of a source: far brighter than all 8 neighbours, which
    // the PSF cannot do (a Gaussian of sigma >= 0.65 px keeps its neighbours above 1/3 of the peak),
    // while the neighbours themselves are well above background. Leave that pixel out and carry on
    // with the source from its brightest neighbour.
    for (int pass = 0; pass < 2; ++pass) {
      const double p = img.at(pk.x, pk.y) - level;
      double nmax = -1e300;
      int bx = pk.x, by = pk.y;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          if (!(dx || dy)) continue;
          const double v = nb(pk.x + dx, pk.y + dy);
          if (v > nmax) {
            nmax = v;
            bx = std::clamp(pk.x + dx, 0, w - 1);
            by = std::clamp(pk.y + dy, 0, h - 1);
          }
        }
      }
      if (img.at(pk.x, pk.y) >= sat || !opt.reject_hot_pixels || p <= 3 * nmax + 5 * sigma_n || nmax < 5 * sigma_n)
        break;
      bad->Set(pk.x, pk.y);
      rejected->push_back(
          {static_cast<double>(pk.x), static_cast<double>(pk.y), RejectReason::kHotPixel, "on_source", p});
      pk.x = bx;
      pk.y = by;
    }
    const int mx = pk.x, my = pk.y;
    const double p = img.at(mx, my) - level;
    // Mean of opposite neighbours in each of four directions, relative to the peak: a star
    // spreads in every direction, a hot pixel in none, a cosmic-ray track only along itself.
    auto pair_mean = [&](int dx, int dy) {
      double a = nb(mx + dx, my + dy), b = nb(mx - dx, my - dy);
      const int ax = mx + dx, ay = my + dy, bx2 = mx - dx, by2 = my - dy;
      if (ax >= 0 && ay >= 0 && ax < w && ay < h && bad->Get(ax, ay)) a = b;
      if (bx2 >= 0 && by2 >= 0 && bx2 < w && by2 < h && bad->Get(bx2, by2)) b = a;
      return 0.5 * (a + b);
    };
    const double dirs[4] = {pair_mean(1, 0), pair_mean(0, 1), pair_mean(1, 1), pair_mean(1, -1)};
    const double dmax = *std::max_element(dirs, dirs + 4), dmin = *std::min_element(dirs, dirs + 4);
    ps.dir_ratio[pi] = p > 0 ? dmin / p : 1.0;
    ps.peak_above[pi] = p;
    const bool saturated_peak = img.at(mx, my) >= sat;
    if (!saturated_peak && opt.reject_hot_pixels && p > 0 && dmax < 0.2 * p && dmax < p - 3 * sigma_n) {
      ps.is_spike[pi] = true;
      bad->Set(mx, my);
      rejected->push_back({static_cast<double>(mx), static_cast<double>(my), RejectReason::kHotPixel, "", p});
    }
  }
  // Distances between the remaining peaks of a blob (spikes do not make a star blended).
  for (size_t pi = 0; pi < peaks.size(); ++pi) {
    peaks[pi].nearest_px = 1e9;
    if (ps.is_spike[pi]) continue;
    for (size_t q = bp->first[peaks[pi].blob]; q < bp->first[peaks[pi].blob + 1]; ++q) {
      if (q != pi && !ps.is_spike[q]) {
        peaks[pi].nearest_px =
            std::min(peaks[pi].nearest_px, std::hypot(peaks[q].x - peaks[pi].x, peaks[q].y - peaks[pi].y));
      }
    }
  }
  return ps;
}

// Step 5b: a PSF fit at each remaining peak, brightest first and at most 3 x max_stars of them: on a
// frame full of faint structure the rest could not enter the output anyway, and each fit costs tens
// of microseconds. `view` (the raw frame) counts saturated pixels.
std::vector<Candidate> FitCandidates(const ImageView& img, const ImageView& view, const BackgroundGrid& bg,
                                     const DetectOptions& opt, double psf_guess, const BlobPeaks& bp,
                                     const PeakShape& ps, const PixelMask& bad) {
  const int w = img.width, h = img.height;
  const double sat = opt.saturation_adu;
  const std::vector<Peak>& peaks = bp.peaks;
  const int fit_r =
      std::max(3, static_cast<int>(std::ceil(2.5 * psf_guess)));  // +-2.5 sigma holds the position information
  std::vector<size_t> order;
  for (size_t pi = 0; pi < peaks.size(); ++pi) {
    if (!ps.is_spike[pi]) order.push_back(pi);
  }
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return peaks[a].score > peaks[b].score; });
  if (order.size() > static_cast<size_t>(3 * opt.max_stars)) order.resize(static_cast<size_t>(3 * opt.max_stars));
  std::vector<Candidate> cands;
  cands.reserve(order.size());
  for (size_t pi : order) {
    const Peak& pk = peaks[pi];
    Candidate c;
    c.peak = pi;
    c.peak_above = ps.peak_above[pi];
    c.min_dir_ratio = ps.dir_ratio[pi];
    for (int y = std::max(0, pk.y - fit_r); y <= std::min(h - 1, pk.y + fit_r); ++y) {
      for (int x = std::max(0, pk.x - fit_r); x <= std::min(w - 1, pk.x + fit_r); ++x) c.nsat += view.at(x, y) >= sat;
    }
    PsfFitOptions fo;
    fo.sigma_guess_px = psf_guess;
    fo.gain_e_per_adu = opt.gain_e_per_adu;
    fo.saturation_adu = sat;
    fo.fit = opt.fit_gaussian;
    if (opt.smear.active()) {
      const Vec2 d = opt.smear.DisplacementPx(Vec2(pk.x, pk.y));
      if (d.norm() >= opt.smear.min_px) {
        fo.smear_dx_px = d.x();
        fo.smear_dy_px = d.y();
        c.smear_px = d.norm();
      }
    }
    // Pixels nearer another peak of the same blob belong to that source (Voronoi split).
    auto excluded = [&](int x, int y) {
      if (bad.Get(x, y)) return true;
      if (pk.nearest_px > 2 * fit_r + 2) return false;
      const double d0 = (x - pk.x) * (x - pk.x) + (y - pk.y) * (y - pk.y);
      for (size_t q = bp.first[pk.blob]; q < bp.first[pk.blob + 1]; ++q) {
        if (q == pi) continue;
        const double d1 = (x - peaks[q].x) * (x - peaks[q].x) + (y - peaks[q].y) * (y - peaks[q].y);
        if (d1 < d0) return true;
      }
      return false;
    };
    c.fit = FitPsf(img, pk.x, pk.y, fit_r, bg.LevelAt(pk.x, pk.y), bg.SigmaAt(pk.x, pk.y), fo, excluded);
    cands.push_back(c);
  }
  return cands;
}

// Step 5c: the frame's PSF width, the median fitted sigma of the brightest unsaturated, isolated
// sources that are not single-pixel sharp (or as given).
double FramePsfSigma(const std::vector<Candidate>& cands, const std::vector<Peak>& peaks, double given_px,
                     double psf_guess) {
  if (given_px > 0) return given_px;
  std::vector<std::pair<double, double>> bright;  // (peak above background, sigma)
  for (const Candidate& c : cands) {
    if (c.fit.ok && c.nsat == 0 && c.fit.snr > 15 && c.min_dir_ratio > 0.02 && peaks[c.peak].nearest_px > 8 &&
        c.fit.sigma_px > 0.31) {
      bright.emplace_back(c.peak_above, c.fit.sigma_px);  // ranked by peak: broad noise blobs rank low
    }
  }
  std::sort(bright.begin(), bright.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (bright.size() > 25) bright.resize(25);
  std::vector<double> s;
  for (const auto& b : bright) s.push_back(b.second);
  return s.size() < 3 ? psf_guess : Median(std::move(s));
}

// Step 5d: is the candidate an interferer? Sets rej and returns true for a cosmic ray, hot pixel,
// streak or extended object (or a blended pair, which cannot be centroided without bias).
bool Interferer(const Candidate& c, const Peak& pk, const Blob& b, const std::vector<Run>& runs, double psf,
                double sharp_ratio, double sigma_n, Rejection* rej) {
  const PsfFit& f = c.fit;
  const double ext_x = b.x1 - b.x0 + 1, ext_y = b.y1 - b.y0 + 1;
  const double length = std::hypot(ext_x, ext_y);
  rej->x_px = f.ok ? f.x_px : pk.x;
  rej->y_px = f.ok ? f.y_px : pk.y;
  rej->flux_adu = f.flux_adu;
  // Sharper than the PSF: a neighbour pair far below what the PSF gives, and (where the fit
  // worked) a fitted width well under the frame's PSF.
  const bool significant_sharp = c.min_dir_ratio < sharp_ratio &&
                                 c.peak_above * (sharp_ratio - c.min_dir_ratio) > 2.0 * sigma_n &&
                                 (!f.ok || f.sigma_px < 0.75 * psf || f.elongation > 1.6);
  if (c.nsat == 0 && significant_sharp) {
    // Sharper than the PSF across at least one direction: charge deposited in the pixels, not
    // imaged through the optics.
    rej->reason = b.npix <= 2 && length < 3 ? RejectReason::kHotPixel : RejectReason::kCosmicRay;
  } else if (c.nsat == 0 && length > 10 * psf + 6 + c.smear_px && BlobElongation(b, runs) > 3.0) {
    // Long thin blob imaged through the optics: a satellite or aircraft streak.
    rej->reason = RejectReason::kStreak;
  } else if (c.nsat == 0 && b.npix > 400 * psf * psf + 20 * psf * c.smear_px) {
    rej->reason = RejectReason::kExtended;
  } else if (c.nsat > 400) {
    rej->reason = RejectReason::kExtended;
    rej->detail = "saturated_extended";
  } else if (c.nsat == 0 && f.ok && f.sigma_px > 2.0 * psf + 0.3 && f.snr > 10) {
    rej->reason = RejectReason::kExtended;
  } else if (pk.nearest_px < 2.9 * psf) {
    // Two peaks too close to centroid apart without bias.
    rej->reason = RejectReason::kExtended;
    rej->detail = "blended_pair";
  } else if (c.nsat == 0 && f.ok && f.elongation > 1.8 && f.snr > 30) {
    rej->reason = RejectReason::kExtended;
    rej->detail = "elongated";
  } else {
    return false;
  }
  return true;
}

// Step 6: dead pixels and defect-map pixels that would otherwise have looked like sources, up to
// a cap on the report's length.
void ReportDefects(const ImageView& view, const BackgroundGrid& bg, const DetectOptions& opt,
                   const std::vector<std::pair<int, int>>& dead_pixels, const DefectMap* defects,
                   std::vector<Rejection>* rejected) {
  constexpr size_t kMaxReported = 2000;
  for (const auto& [x, y] : dead_pixels) {
    if (rejected->size() >= kMaxReported) break;
    rejected->push_back({static_cast<double>(x), static_cast<double>(y), RejectReason::kDeadPixel, "", 0});
  }
  if (!defects) return;
  for (int y = 0; y < view.height && rejected->size() < kMaxReported; ++y) {
    for (int x = 0; x < view.width; ++x) {
      if (!defects->at(x, y)) continue;
      const double above = view.at(x, y) - bg.LevelAt(x, y);
      if (above > opt.threshold_sigma * bg.SigmaAt(x, y)) {
        rejected->push_back({static_cast<double>(x), static_cast<double>(y), RejectReason::kDefectMap, "", above});
      }
    }
  }
}

}  // namespace

const char* RejectReasonName(RejectReason r) {
  switch (r) {
    case RejectReason::kHotPixel:
      return "hot_pixel";
    case RejectReason::kDeadPixel:
      return "dead_pixel";
    case RejectReason::kDefectMap:
      return "defect_map";
    case RejectReason::kCosmicRay:
      return "cosmic_ray";
    case RejectReason::kStreak:
      return "streak";
    case RejectReason::kExtended:
      return "extended";
  }
  return "unknown";
}

void DetectOptions::Check() const {
  auto need = [](bool ok, const char* what) {
    if (!ok) throw InputError(std::string("DetectOptions: ") + what);
  };
  need(std::isfinite(threshold_sigma) && threshold_sigma >= 2 && threshold_sigma <= 100,
       "threshold_sigma must be in [2, 100]");
  need(std::isfinite(min_snr) && min_snr >= 0, "min_snr must be >= 0");
  need(tile_px >= 8 && tile_px <= 1024, "tile_px must be in [8, 1024]");
  need(std::isfinite(psf_sigma_px) && psf_sigma_px >= 0 && psf_sigma_px < 50, "psf_sigma_px must be in [0, 50)");
  need(std::isfinite(gain_e_per_adu) && gain_e_per_adu >= 0, "gain_e_per_adu must be >= 0");
  need(std::isfinite(saturation_adu) && saturation_adu > 0, "saturation_adu must be > 0");
  need(std::isfinite(dead_sigma) && dead_sigma > 2, "dead_sigma must be > 2");
  need(max_stars > 0, "max_stars must be > 0");
  smear.Check();
}

Detections Detect(const ImageView& view, const DetectOptions& opt, const DefectMap* defects) {
  opt.Check();
  const auto t_start = Clock::now();
  const int w = view.width, h = view.height;
  if (w < 16 || h < 16 || view.data == nullptr) throw InputError("Detect: image smaller than 16x16");
  if (defects && !defects->empty() && (defects->width != w || defects->height != h)) {
    throw InputError("Detect: defect map size differs from the image");
  }
  if (opt.smear.active() && (opt.smear.camera.width != w || opt.smear.camera.height != h)) {
    throw InputError("Detect: smear.camera size differs from the image");
  }
  Detections out;
  out.width = w;
  out.height = h;
  const DefectMap* known = defects && !defects->empty() ? defects : nullptr;
  std::vector<uint16_t> repaired;
  const ImageView img = known ? RepairDefects(view, *known, &repaired) : view;

  // 1. Background and noise per tile (median and MAD: robust to stars and hot pixels).
  auto t0 = Clock::now();
  // Matched filter: a box of about the PSF's size (3x3 is 88% efficient for sigma 1.2 px).
  const double psf_guess = opt.psf_sigma_px > 0 ? opt.psf_sigma_px : 1.2;
  const int half = psf_guess <= 1.6 ? 1 : (psf_guess <= 2.8 ? 2 : 3);
  const BackgroundGrid bg = EstimateBackground(img, opt.tile_px, half);
  out.background_adu = bg.median_level;
  out.noise_adu = bg.median_sigma;
  out.timing_ms["background"] = MsSince(t0);

  // 2. Threshold the box sum on its own measured local noise.
  t0 = Clock::now();
  std::vector<Run> runs;
  std::vector<std::pair<int, int>> dead_pixels;
  ThresholdRuns(img, view, bg, opt, half, known, &runs, &dead_pixels);
  out.timing_ms["threshold"] = MsSince(t0);

  // 3. Connected blobs.
  t0 = Clock::now();
  std::vector<Blob> blobs = ConnectBlobs(runs);
  out.timing_ms["blobs"] = MsSince(t0);

  // 4. Peaks inside each blob.
  t0 = Clock::now();
  BlobPeaks bp = FindPeaks(img, bg, blobs, runs);

  // 5. Classify each peak: spikes, then PSF fits, the frame's PSF, interferers, stars.
  PixelMask bad(w, h);
  for (const auto& [x, y] : dead_pixels) bad.Set(x, y);
  if (known) {
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        if (known->at(x, y)) bad.Set(x, y);
      }
    }
  }
  const PeakShape ps = ClassifySpikes(img, bg, opt, &bp, &bad, &out.rejected);
  const std::vector<Candidate> cands = FitCandidates(img, view, bg, opt, psf_guess, bp, ps, bad);
  const double psf = FramePsfSigma(cands, bp.peaks, opt.psf_sigma_px, psf_guess);
  out.psf_sigma_px = psf;
  const double sharp_ratio = std::clamp(0.45 * DiagonalRatio(psf), 0.02, 0.3);
  std::vector<bool> blob_reported(blobs.size(), false);  // one track/streak rejection per blob
  for (const Candidate& c : cands) {
    const Peak& pk = bp.peaks[c.peak];
    const Blob& b = blobs[pk.blob];
    const PsfFit& f = c.fit;
    Rejection rej;
    if (Interferer(c, pk, b, runs, psf, sharp_ratio, bg.SigmaAt(pk.x, pk.y), &rej)) {
      const bool per_blob = rej.reason == RejectReason::kCosmicRay || rej.reason == RejectReason::kStreak;
      if (!(per_blob && blob_reported[pk.blob])) out.rejected.push_back(rej);
      if (per_blob) blob_reported[pk.blob] = true;
      continue;
    }
    if (!f.ok || f.snr < opt.min_snr) continue;
    StarDetection s;
    s.x_px = f.x_px;
    s.y_px = f.y_px;
    s.flux_adu = f.flux_adu;
    s.peak_adu = c.peak_above;
    s.snr = f.snr;
    s.npix = b.npix;
    s.saturated = c.nsat > 0;
    s.sigma_px = f.sigma_px;
    s.x_sigma_px = f.x_sigma_px;
    s.y_sigma_px = f.y_sigma_px;
    out.stars.push_back(s);
  }
  std::sort(out.stars.begin(), out.stars.end(),
            [](const StarDetection& a, const StarDetection& b) { return a.flux_adu > b.flux_adu; });
  if (static_cast<int>(out.stars.size()) > opt.max_stars) out.stars.resize(opt.max_stars);

  // 6. Defective pixels in the report.
  ReportDefects(view, bg, opt, dead_pixels, known, &out.rejected);
  out.timing_ms["centroid"] = MsSince(t0);
  out.timing_ms["total"] = MsSince(t_start);
  return out;
}

}  // namespace ssiu
