#include "detect/detect.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "core/error.h"
#include "detect/background.h"
#include "detect/psf_fit.h"
#include "detect/row_kernels.h"

namespace ssiu {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

// The lists' room (DetectLimits; SIZE_MAX everywhere with grow).
struct Caps {
  size_t runs, blobs, peaks, blob_maxima, rejections, dead_pixels;
};

// Appends x unless `v` already holds `cap` entries; then sets `bit` in *clamped instead: a list never
// grows past its limit (nor allocates, when reserved for it).
template <class V, class T>
bool PushCapped(V* v, size_t cap, const T& x, unsigned bit, unsigned* clamped) {
  if (v->size() >= cap) {
    *clamped |= bit;
    return false;
  }
  v->push_back(x);
  return true;
}

Rejection MakeRejection(double x, double y, RejectReason reason, RejectDetail detail, double flux, bool diagnostics) {
  Rejection r;
  r.x_px = x;
  r.y_px = y;
  r.reason = reason;
  r.detail_code = detail;
  if (diagnostics && detail != RejectDetail::kNone) r.detail = RejectDetailName(detail);
  r.flux_adu = flux;
  return r;
}

// A horizontal run of above-threshold pixels [x0, x1] in row y, and its blob label.
struct Run {
  int y, x0, x1;
  int label;
};

int FindRoot(ScratchVec<int>& parent, int i) {
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
  int run_begin = 0, run_end = 0;  // its runs: blob_runs[run_begin .. run_end), in row order
};

// The runs and their blobs: the runs of blob b are runs[blob_runs[b.run_begin .. b.run_end)].
struct BlobSet {
  const ScratchVec<Run>& runs;
  const ScratchVec<Blob>& blobs;
  const ScratchVec<int>& blob_runs;
  const Run& RunOf(int q) const { return runs[blob_runs[q]]; }
};

// sqrt of the ratio of the principal second moments of a blob's pixels (1 round, large thin).
double BlobElongation(const Blob& b, const BlobSet& bs) {
  double n = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  for (int q = b.run_begin; q < b.run_end; ++q) {
    const Run& r = bs.RunOf(q);
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
  explicit PixelMask(std::pmr::memory_resource* mr = std::pmr::get_default_resource()) : bits_(mr) {}
  void Reserve(int w, int h) { bits_.reserve((static_cast<size_t>(w) * h + 63) / 64); }
  void Reset(int w, int h) {
    w_ = w;
    bits_.assign((static_cast<size_t>(w) * h + 63) / 64, 0);
  }
  void Set(int x, int y) {
    const size_t i = static_cast<size_t>(y) * w_ + x;
    bits_[i >> 6] |= uint64_t{1} << (i & 63);
  }
  size_t Bytes() const;
  bool Get(int x, int y) const {
    const size_t i = static_cast<size_t>(y) * w_ + x;
    return ((bits_[i >> 6] >> (i & 63)) & 1) != 0;
  }

 private:
  int w_ = 0;
  ScratchVec<uint64_t> bits_;
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
  explicit BlobPeaks(std::pmr::memory_resource* mr = std::pmr::get_default_resource()) : peaks(mr), first(mr) {}
  ScratchVec<Peak> peaks;
  ScratchVec<size_t> first;
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
ImageView RepairDefects(const ImageView& view, const DefectMap& defects, ScratchVec<uint16_t>* repaired) {
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
struct ThresholdBuffers {
  explicit ThresholdBuffers(std::pmr::memory_resource* mr = std::pmr::get_default_resource())
      : colsum(mr), low_row(mr), thr_centres(mr), above(mr) {}
  ScratchVec<int32_t> colsum;
  ScratchVec<float> low_row, thr_centres;
  ScratchVec<uint8_t> above;
};

void ThresholdRuns(const ImageView& img, const ImageView& view, const BackgroundGrid& bg, const DetectOptions& opt,
                   int half, const DefectMap* defects, const Caps& caps, ThresholdBuffers* tb, ScratchVec<Run>* runs,
                   ScratchVec<std::pair<int, int>>* dead_pixels, unsigned* clamped) {
  const int w = img.width, h = img.height, box = 2 * half + 1;
  // A row whose minimum is above the highest "dead" level of any tile needs no per-pixel test.
  double dead_level_max = -1e300;
  for (size_t k = 0; k < bg.level.size(); ++k) {
    dead_level_max = std::max(dead_level_max, double(bg.level[k]) - opt.dead_sigma * bg.sigma[k]);
  }
  ScratchVec<int32_t>& colsum = tb->colsum;
  ScratchVec<float>&low_row = tb->low_row, &thr_centres = tb->thr_centres;
  ScratchVec<uint8_t>& above = tb->above;
  colsum.assign(static_cast<size_t>(w), 0);
  low_row.resize(static_cast<size_t>(w));
  above.assign(static_cast<size_t>(w) + 1, 0);
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
        if (raw[x] < low_row[x] && !(defects && defects->at(x, yc))) {
          PushCapped(dead_pixels, caps.dead_pixels, std::make_pair(x, yc), kClampDeadPixels, clamped);
        }
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
        PushCapped(runs, caps.runs, Run{yc, xs, x - 1, -1}, kClampRuns, clamped);
      }
    }
    // Slide the column sums down one row.
    if (yc + half + 1 < h) SlideColumnSums(cs, img.row(yc + half + 1), img.row(yc - half), w);
  }
}

// Step 3: connected blobs of runs (8-connectivity), union-find over runs of adjacent rows; each
// blob's runs listed in blob_runs in run order. Runs beyond caps.blobs blobs join none.
struct BlobBuffers {
  explicit BlobBuffers(std::pmr::memory_resource* mr = std::pmr::get_default_resource())
      : parent(mr), blob_of(mr), blob_runs(mr), blobs(mr) {}
  ScratchVec<int> parent, blob_of, blob_runs;
  ScratchVec<Blob> blobs;
};

void ConnectBlobs(const ScratchVec<Run>& runs, const Caps& caps, BlobBuffers* bb, unsigned* clamped) {
  ScratchVec<int>& parent = bb->parent;
  ScratchVec<Blob>& blobs = bb->blobs;
  parent.resize(runs.size());
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
  blobs.clear();
  // blob_of[root]: the blob of each root run (-1: none).
  ScratchVec<int>& blob_of = bb->blob_of;
  blob_of.assign(runs.size(), -1);
  for (size_t k = 0; k < runs.size(); ++k) {
    const int root = FindRoot(parent, static_cast<int>(k));
    if (blob_of[root] < 0) {
      if (blobs.size() >= caps.blobs) {
        *clamped |= kClampBlobs;
        continue;
      }
      blob_of[root] = static_cast<int>(blobs.size());
      blobs.emplace_back();
    }
    Blob& b = blobs[blob_of[root]];
    const Run& r = runs[k];
    ++b.run_end;  // a count until the offsets below
    b.x0 = std::min(b.x0, r.x0);
    b.x1 = std::max(b.x1, r.x1);
    b.y0 = std::min(b.y0, r.y);
    b.y1 = std::max(b.y1, r.y);
    b.npix += r.x1 - r.x0 + 1;
  }
  // Counting sort of the runs by blob, keeping run order within a blob.
  int offset = 0;
  for (Blob& b : blobs) {
    const int n = b.run_end;
    b.run_begin = b.run_end = offset;
    offset += n;
  }
  ScratchVec<int>& blob_runs = bb->blob_runs;
  blob_runs.resize(static_cast<size_t>(offset));
  for (size_t k = 0; k < runs.size(); ++k) {
    const int bi = blob_of[FindRoot(parent, static_cast<int>(k))];
    if (bi >= 0) blob_runs[blobs[bi].run_end++] = static_cast<int>(k);
  }
}

// 3x3 sums of the image over a blob's bounding box plus a one-pixel margin (edge pixels
// replicated), computed once per blob from horizontal 3-sums: the peak search reads each sum about
// ten times. A blob whose box exceeds the grid's room (kMaxPx) has its sums computed where read
// (the same integers).
struct ScoreGrid {
  explicit ScoreGrid(std::pmr::memory_resource* mr = std::pmr::get_default_resource()) : v(mr), hs(mr) {}
  static constexpr size_t kMaxPx = 128 * 128;
  const ImageView* img = nullptr;
  bool grow = false;  // the buffers grow to any blob (Detect's one-call form)
  bool direct = false;
  int x0 = 0, y0 = 0, gw = 0, gh = 0;
  ScratchVec<int32_t> v, hs;
  void Reserve() {
    v.reserve(kMaxPx);
    hs.reserve(2 * kMaxPx);  // gw (gh + 2) <= 5/3 gw gh, as gh >= 3
  }
  int32_t at(int x, int y) const { return direct ? Direct(x, y) : v[static_cast<size_t>(y - y0) * gw + (x - x0)]; }
  int32_t Direct(int x, int y) const {
    const int w = img->width, h = img->height;
    const int xc = std::clamp(x, 0, w - 1), xl = std::max(xc - 1, 0), xr = std::min(xc + 1, w - 1);
    int32_t sum = 0;
    for (int dy = -1; dy <= 1; ++dy) {
      const uint16_t* row = img->row(std::clamp(y + dy, 0, h - 1));
      sum += row[xl] + row[xc] + row[xr];
    }
    return sum;
  }
  void Fill(const ImageView& image, const Blob& b) {
    img = &image;
    const int w = image.width, h = image.height;
    x0 = b.x0 - 1;
    y0 = b.y0 - 1;
    gw = b.x1 - b.x0 + 3;
    gh = b.y1 - b.y0 + 3;
    const size_t nhs = static_cast<size_t>(gw) * (gh + 2), nv = static_cast<size_t>(gw) * gh;
    direct = !grow && (nhs > hs.capacity() || nv > v.capacity());
    if (direct) return;
    hs.resize(nhs);
    v.resize(nv);
    for (int r = 0; r < gh + 2; ++r) {
      const uint16_t* row = image.row(std::clamp(y0 - 1 + r, 0, h - 1));
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

// The local maxima of the 3x3 sum over the blob's pixels, brightest first, into *local (at most cap).
void LocalMaxima(const ScoreGrid& grid, const BlobSet& bs, const Blob& b, double level9, size_t bi, size_t cap,
                 ScratchVec<Peak>* local, unsigned* clamped) {
  local->clear();
  for (int q = b.run_begin; q < b.run_end; ++q) {
    const Run& r = bs.RunOf(q);
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
      if (is_max) PushCapped(local, cap, Peak{x, r.y, c - level9, bi}, kClampBlobMaxima, clamped);
    }
  }
  std::sort(local->begin(), local->end(), [](const Peak& p, const Peak& q) { return p.score > q.score; });
}

// Step 4: peaks, the local maxima of the 3x3-summed image inside each blob, kept when a real dip
// separates them from every brighter peak (so a star beside another star or a hot pixel is not
// lost), each moved to the brightest raw pixel next to it.
struct PeakBuffers {
  explicit PeakBuffers(std::pmr::memory_resource* mr = std::pmr::get_default_resource())
      : grid(mr), local(mr), kept(mr) {}
  ScoreGrid grid;
  ScratchVec<Peak> local, kept;
};
constexpr size_t kMaxPeaksPerBlob = 12;

void FindPeaks(const ImageView& img, const BackgroundGrid& bg, ScratchVec<Blob>& blobs, const BlobSet& bs,
               const Caps& caps, PeakBuffers* pb, BlobPeaks* out, unsigned* clamped) {
  const int w = img.width, h = img.height;
  ScoreGrid& grid = pb->grid;
  ScratchVec<Peak>& kept = pb->kept;
  out->peaks.clear();
  out->first.assign(blobs.size() + 1, 0);
  for (size_t bi = 0; bi < blobs.size(); ++bi) {
    out->first[bi] = out->peaks.size();
    Blob& b = blobs[bi];
    grid.Fill(img, b);
    // Peak of the raw image inside the blob (3x3-smoothed score to be robust to noise).
    for (int q = b.run_begin; q < b.run_end; ++q) {
      const Run& r = bs.RunOf(q);
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
    kept.clear();
    LocalMaxima(grid, bs, b, level9, bi, caps.blob_maxima, &pb->local, clamped);
    for (const Peak& m : pb->local) {
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
      PushCapped(&out->peaks, caps.peaks, p, kClampPeaks, clamped);
    }
  }
  out->first[blobs.size()] = out->peaks.size();
}

// Per-peak figures of step 5a.
struct PeakShape {
  explicit PeakShape(std::pmr::memory_resource* mr = std::pmr::get_default_resource())
      : is_spike(mr), dir_ratio(mr), peak_above(mr) {}
  ScratchVec<uint8_t> is_spike;
  ScratchVec<double> dir_ratio, peak_above;
};

// Step 5a: single-pixel spikes found first (and masked), so that the fits of stars beside them
// leave them out. A hot pixel on top of a source is masked and the peak moved off it.
void ClassifySpikes(const ImageView& img, const BackgroundGrid& bg, const DetectOptions& opt, const Caps& caps,
                    bool diagnostics, BlobPeaks* bp, PixelMask* bad, PeakShape* shape, ScratchVec<Rejection>* rejected,
                    unsigned* clamped) {
  const int w = img.width, h = img.height;
  const double sat = opt.saturation_adu;
  ScratchVec<Peak>& peaks = bp->peaks;
  PeakShape& ps = *shape;
  ps.is_spike.assign(peaks.size(), 0);
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
      PushCapped(rejected, caps.rejections,
                 MakeRejection(pk.x, pk.y, RejectReason::kHotPixel, RejectDetail::kOnSource, p, diagnostics),
                 kClampRejections, clamped);
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
      ps.is_spike[pi] = 1;
      bad->Set(mx, my);
      PushCapped(rejected, caps.rejections,
                 MakeRejection(mx, my, RejectReason::kHotPixel, RejectDetail::kNone, p, diagnostics), kClampRejections,
                 clamped);
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
}

// Step 5b: a PSF fit at each remaining peak, brightest first and at most 3 x max_stars of them: on a
// frame full of faint structure the rest could not enter the output anyway, and each fit costs tens
// of microseconds. `view` (the raw frame) counts saturated pixels.
struct FitBuffers {
  explicit FitBuffers(std::pmr::memory_resource* mr = std::pmr::get_default_resource())
      : order(mr), cands(mr), scratch(mr) {}
  ScratchVec<size_t> order;
  ScratchVec<Candidate> cands;
  PsfFitScratch scratch;
};

// max_fits: 3 x the stars kept; max_half_px: the PSF-fit window's room (0: none).
void FitCandidates(const ImageView& img, const ImageView& view, const BackgroundGrid& bg, const DetectOptions& opt,
                   double psf_guess, const BlobPeaks& bp, const PeakShape& ps, const PixelMask& bad, size_t max_fits,
                   int max_half_px, FitBuffers* fb, unsigned* clamped) {
  const int w = img.width, h = img.height;
  const double sat = opt.saturation_adu;
  const ScratchVec<Peak>& peaks = bp.peaks;
  const int fit_r =
      std::max(3, static_cast<int>(std::ceil(2.5 * psf_guess)));  // +-2.5 sigma holds the position information
  ScratchVec<size_t>& order = fb->order;
  ScratchVec<Candidate>& cands = fb->cands;
  order.clear();
  cands.clear();
  for (size_t pi = 0; pi < peaks.size(); ++pi) {
    if (!ps.is_spike[pi]) order.push_back(pi);  // order holds as many as peaks
  }
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return peaks[a].score > peaks[b].score; });
  if (order.size() > max_fits) order.resize(max_fits);
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
    fo.max_half_px = max_half_px;
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
    c.fit = FitPsf(img, pk.x, pk.y, fit_r, bg.LevelAt(pk.x, pk.y), bg.SigmaAt(pk.x, pk.y), fo, excluded, &fb->scratch);
    if (c.fit.window_clamped) *clamped |= kClampFitWindow;
    cands.push_back(c);  // cands holds max_fits
  }
}

// Step 5c: the frame's PSF width, the median fitted sigma of the brightest unsaturated, isolated
// sources that are not single-pixel sharp (or as given; psf_guess when fewer than 3); *source says which.
double FramePsfSigma(const ScratchVec<Candidate>& cands, const ScratchVec<Peak>& peaks, double given_px,
                     double psf_guess, ScratchVec<std::pair<double, double>>* bright_buffer, const char** source) {
  *source = given_px > 0 ? "given" : "assumed";
  if (given_px > 0) return given_px;
  ScratchVec<std::pair<double, double>>& bright = *bright_buffer;  // (peak above background, sigma)
  bright.clear();
  for (const Candidate& c : cands) {
    if (c.fit.ok && c.nsat == 0 && c.fit.snr > 15 && c.min_dir_ratio > 0.02 && peaks[c.peak].nearest_px > 8 &&
        c.fit.sigma_px > 0.31) {
      bright.emplace_back(c.peak_above, c.fit.sigma_px);  // ranked by peak: broad noise blobs rank low
    }
  }
  std::sort(bright.begin(), bright.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (bright.size() > 25) bright.resize(25);
  if (bright.size() < 3) return psf_guess;
  *source = "measured";
  // The upper median of the sigmas (core/stats.h Median), selected in place.
  std::array<double, 25> s;
  for (size_t k = 0; k < bright.size(); ++k) s[k] = bright[k].second;
  const size_t m = bright.size() / 2;
  std::nth_element(s.begin(), s.begin() + m, s.begin() + bright.size());
  return s[m];
}

// Step 5d: is the candidate an interferer? Sets rej and returns true for a cosmic ray, hot pixel,
// streak or extended object (or a blended pair, which cannot be centroided without bias).
bool Interferer(const Candidate& c, const Peak& pk, const Blob& b, const BlobSet& bs, double psf, double sharp_ratio,
                double sigma_n, Rejection* rej) {
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
  } else if (c.nsat == 0 && length > 10 * psf + 6 + c.smear_px && BlobElongation(b, bs) > 3.0) {
    // Long thin blob imaged through the optics: a satellite or aircraft streak.
    rej->reason = RejectReason::kStreak;
  } else if (c.nsat == 0 && b.npix > 400 * psf * psf + 20 * psf * c.smear_px) {
    rej->reason = RejectReason::kExtended;
  } else if (c.nsat > 400) {
    rej->reason = RejectReason::kExtended;
    rej->detail_code = RejectDetail::kSaturatedExtended;
  } else if (c.nsat == 0 && f.ok && f.sigma_px > 2.0 * psf + 0.3 && f.snr > 10) {
    rej->reason = RejectReason::kExtended;
  } else if (pk.nearest_px < 2.9 * psf) {
    // Two peaks too close to centroid apart without bias.
    rej->reason = RejectReason::kExtended;
    rej->detail_code = RejectDetail::kBlendedPair;
  } else if (c.nsat == 0 && f.ok && f.elongation > 1.8 && f.snr > 30) {
    rej->reason = RejectReason::kExtended;
    rej->detail_code = RejectDetail::kElongated;
  } else {
    return false;
  }
  return true;
}

// Step 6: dead pixels and defect-map pixels that would otherwise have looked like sources, up to
// a cap on the report's length.
void ReportDefects(const ImageView& view, const BackgroundGrid& bg, const DetectOptions& opt,
                   const ScratchVec<std::pair<int, int>>& dead_pixels, const DefectMap* defects, const Caps& caps,
                   ScratchVec<Rejection>* rejected, unsigned* clamped) {
  constexpr size_t kMaxReported = 2000;
  for (const auto& [x, y] : dead_pixels) {
    if (rejected->size() >= kMaxReported) break;
    PushCapped(rejected, caps.rejections, MakeRejection(x, y, RejectReason::kDeadPixel, RejectDetail::kNone, 0, false),
               kClampRejections, clamped);
  }
  if (!defects) return;
  for (int y = 0; y < view.height && rejected->size() < kMaxReported; ++y) {
    for (int x = 0; x < view.width; ++x) {
      if (!defects->at(x, y)) continue;
      const double above = view.at(x, y) - bg.LevelAt(x, y);
      if (above > opt.threshold_sigma * bg.SigmaAt(x, y)) {
        PushCapped(rejected, caps.rejections,
                   MakeRejection(x, y, RejectReason::kDefectMap, RejectDetail::kNone, above, false), kClampRejections,
                   clamped);
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

const char* RejectDetailName(RejectDetail d) {
  static constexpr const char* kNames[] = {"", "on_source", "blended_pair", "saturated_extended", "elongated"};
  const auto i = static_cast<size_t>(d);
  return i < std::size(kNames) ? kNames[i] : "";
}

const char* DetectStatusName(DetectStatus s) {
  static constexpr const char* kNames[] = {"ok",           "bad_options",     "image_too_small",  "image_too_large",
                                           "tile_too_small", "defect_map_size", "smear_camera_size"};
  const auto i = static_cast<size_t>(s);
  return i < std::size(kNames) ? kNames[i] : "unknown";
}

const char* DetectOptions::Problem() const {
  if (!(std::isfinite(threshold_sigma) && threshold_sigma >= 2 && threshold_sigma <= 100))
    return "threshold_sigma must be in [2, 100]";
  if (!(std::isfinite(min_snr) && min_snr >= 0)) return "min_snr must be >= 0";
  if (!(tile_px >= 8 && tile_px <= 1024)) return "tile_px must be in [8, 1024]";
  if (!(std::isfinite(psf_sigma_px) && psf_sigma_px >= 0 && psf_sigma_px < 50)) return "psf_sigma_px must be in [0, 50)";
  if (!(std::isfinite(gain_e_per_adu) && gain_e_per_adu >= 0)) return "gain_e_per_adu must be >= 0";
  if (!(std::isfinite(saturation_adu) && saturation_adu > 0)) return "saturation_adu must be > 0";
  if (!(std::isfinite(dead_sigma) && dead_sigma > 2)) return "dead_sigma must be > 2";
  if (!(max_stars > 0)) return "max_stars must be > 0";
  return smear.Problem();
}

void DetectOptions::Check() const {
  if (const char* p = Problem()) throw InputError(std::string("DetectOptions: ") + p);
  smear.Check();  // the camera
}

void DetectLimits::Check() const {
  auto need = [](bool ok, const char* what) {
    if (!ok) throw InputError(std::string("DetectLimits: ") + what);
  };
  need(max_width >= 16 && max_height >= 16, "max_width and max_height must be >= 16");
  need(max_detections > 0, "max_detections must be > 0");
  need(min_tile_px >= 8 && min_tile_px <= 1024, "min_tile_px must be in [8, 1024]");
  need(max_runs > 0 && max_blobs > 0 && max_peaks > 0 && max_blob_maxima > 0 && max_rejections > 0 &&
           max_dead_pixels > 0,
       "max_runs, max_blobs, max_peaks, max_blob_maxima, max_rejections and max_dead_pixels must be > 0");
  need(max_fit_window_px >= 7 && max_fit_window_px <= 1024, "max_fit_window_px must be in [7, 1024]");
}

struct DetectWorkspace::Buffers {
  explicit Buffers(std::pmr::memory_resource* mr)
      : bg_scratch(mr),
        bg(mr),
        repaired(mr),
        threshold(mr),
        runs(mr),
        dead_pixels(mr),
        blobs(mr),
        peak_search(mr),
        peaks(mr),
        bad(mr),
        shape(mr),
        fits(mr),
        bright(mr),
        blob_reported(mr),
        stars(mr) {}
  BackgroundScratch bg_scratch;
  BackgroundGrid bg;
  ScratchVec<uint16_t> repaired;
  ThresholdBuffers threshold;
  ScratchVec<Run> runs;
  ScratchVec<std::pair<int, int>> dead_pixels;
  BlobBuffers blobs;
  PeakBuffers peak_search;
  BlobPeaks peaks;
  PixelMask bad;
  PeakShape shape;
  FitBuffers fits;
  ScratchVec<std::pair<double, double>> bright;
  ScratchVec<uint8_t> blob_reported;
  ScratchVec<StarDetection> stars;  // before the brightest are kept
};

DetectWorkspace::DetectWorkspace(const DetectLimits& limits, std::pmr::memory_resource* mr) : limits_(limits) {
  limits_.Check();
  b_ = MakeInResource<Buffers>(mr, mr);
  const DetectLimits& l = limits_;
  Buffers& b = *b_;
  const size_t w = static_cast<size_t>(l.max_width), h = static_cast<size_t>(l.max_height);
  // Per-pixel and per-row buffers, in both modes.
  b.bg_scratch.Reserve(l.max_width, l.max_height, l.min_tile_px, &b.bg);
  b.threshold.colsum.reserve(w);
  b.threshold.low_row.reserve(w);
  b.threshold.above.reserve(w + 1);
  const int t = std::min(l.min_tile_px, 16);
  b.threshold.thr_centres.reserve(((h + t - 1) / t) * w);
  b.bad.Reserve(l.max_width, l.max_height);
  b.peak_search.kept.reserve(kMaxPeaksPerBlob);
  b.peak_search.grid.grow = l.grow;
  if (l.grow) return;  // lists grow as needed
  b.repaired.reserve(w * h);
  const size_t runs = static_cast<size_t>(l.max_runs), blobs = static_cast<size_t>(l.max_blobs);
  const size_t peaks = static_cast<size_t>(l.max_peaks), fits = 3 * static_cast<size_t>(l.max_detections);
  b.runs.reserve(runs);
  b.dead_pixels.reserve(static_cast<size_t>(l.max_dead_pixels));
  b.blobs.parent.reserve(runs);
  b.blobs.blob_of.reserve(runs);
  b.blobs.blob_runs.reserve(runs);
  b.blobs.blobs.reserve(blobs);
  b.peak_search.grid.Reserve();
  b.peak_search.local.reserve(static_cast<size_t>(l.max_blob_maxima));
  b.peaks.peaks.reserve(peaks);
  b.peaks.first.reserve(blobs + 1);
  b.shape.is_spike.reserve(peaks);
  b.shape.dir_ratio.reserve(peaks);
  b.shape.peak_above.reserve(peaks);
  b.fits.order.reserve(peaks);
  b.fits.cands.reserve(std::min(fits, peaks));
  b.fits.scratch.Reserve(l.max_fit_window_px);
  b.bright.reserve(std::min(fits, peaks));
  b.blob_reported.reserve(blobs);
  b.stars.reserve(std::min(fits, peaks));
}

DetectWorkspace::~DetectWorkspace() = default;
DetectWorkspace::DetectWorkspace(DetectWorkspace&&) noexcept = default;
DetectWorkspace& DetectWorkspace::operator=(DetectWorkspace&&) noexcept = default;

void DetectWorkspace::Reserve(Detections* out) const {
  if (limits_.grow) return;
  out->stars.reserve(static_cast<size_t>(limits_.max_detections));
  out->rejected.reserve(static_cast<size_t>(limits_.max_rejections));
}

namespace {
template <class T>
size_t CapacityBytes(const ScratchVec<T>& v) {
  return v.capacity() * sizeof(T);
}
template <class T, class... More>
size_t CapacityBytes(const ScratchVec<T>& v, const More&... more) {
  return CapacityBytes(v) + CapacityBytes(more...);
}
}  // namespace

size_t PixelMask::Bytes() const { return CapacityBytes(bits_); }

size_t DetectWorkspace::Bytes() const {
  const Buffers& b = *b_;
  const BackgroundScratch& bs = b.bg_scratch;
  const PsfFitScratch& fs = b.fits.scratch;
  return sizeof(Buffers) + CapacityBytes(bs.samples, bs.box_samples, bs.select, bs.hist, bs.grid) +
         CapacityBytes(b.bg.level, b.bg.sigma, b.bg.box_sigma, b.repaired) +
         CapacityBytes(b.threshold.colsum, b.threshold.low_row, b.threshold.thr_centres, b.threshold.above) +
         CapacityBytes(b.runs, b.dead_pixels, b.blobs.parent, b.blobs.blob_of, b.blobs.blob_runs, b.blobs.blobs) +
         CapacityBytes(b.peak_search.grid.v, b.peak_search.grid.hs, b.peak_search.local, b.peak_search.kept) +
         CapacityBytes(b.peaks.peaks, b.peaks.first, b.shape.is_spike, b.shape.dir_ratio, b.shape.peak_above) +
         b.bad.Bytes() + CapacityBytes(b.fits.order, b.fits.cands, b.bright, b.blob_reported, b.stars) +
         CapacityBytes(fs.v, fs.w_cur, fs.w_new, fs.use, fs.sm.f, fs.sm.dx, fs.sm.dy, fs.sm.ds) +
         CapacityBytes(fs.fx.f, fs.fx.dc, fs.fx.ds, fs.fy.f, fs.fy.dc, fs.fy.ds) +
         CapacityBytes(fs.sm.px.f, fs.sm.px.dc, fs.sm.px.ds, fs.sm.py.f, fs.sm.py.dc, fs.sm.py.ds);
}

size_t DetectWorkspace::OutputBytes() const {
  if (limits_.grow) return 0;
  return static_cast<size_t>(limits_.max_detections) * sizeof(StarDetection) +
         static_cast<size_t>(limits_.max_rejections) * sizeof(Rejection);
}

DetectStatus Detect(const ImageView& view, const DetectOptions& opt, const DefectMap* defects, DetectWorkspace* ws,
                    Detections* out) {
  const DetectLimits& lim = ws->limits_;
  DetectWorkspace::Buffers& bu = *ws->b_;
  const bool diag = lim.diagnostics;
  const auto now = [diag] { return diag ? Clock::now() : Clock::time_point{}; };
  const auto t_start = now();
  out->width = out->height = 0;
  out->background_adu = out->noise_adu = out->psf_sigma_px = 0;
  out->psf_source = "assumed";
  out->block_artefact_ratio = 1, out->block_artefacts = false;
  out->stars.clear();
  out->rejected.clear();
  out->timing_ms.clear();
  out->clamped = 0;
  if (opt.Problem()) return DetectStatus::kBadOptions;
  const int w = view.width, h = view.height;
  if (w < 16 || h < 16 || view.data == nullptr) return DetectStatus::kImageTooSmall;
  if (w > lim.max_width || h > lim.max_height) return DetectStatus::kImageTooLarge;
  if (defects && !defects->empty() && (defects->width != w || defects->height != h)) {
    return DetectStatus::kDefectMapSize;
  }
  if (opt.smear.active() && (opt.smear.camera.width != w || opt.smear.camera.height != h)) {
    return DetectStatus::kSmearCameraSize;
  }
  if (opt.tile_px < lim.min_tile_px) return DetectStatus::kTileTooSmall;
  constexpr size_t kAny = std::numeric_limits<size_t>::max();
  const Caps caps = lim.grow ? Caps{kAny, kAny, kAny, kAny, kAny, kAny}
                             : Caps{static_cast<size_t>(lim.max_runs),       static_cast<size_t>(lim.max_blobs),
                                    static_cast<size_t>(lim.max_peaks),      static_cast<size_t>(lim.max_blob_maxima),
                                    static_cast<size_t>(lim.max_rejections), static_cast<size_t>(lim.max_dead_pixels)};
  const int max_stars = std::min(opt.max_stars, lim.max_detections);
  unsigned* clamped = &out->clamped;
  out->width = w;
  out->height = h;
  const DefectMap* known = defects && !defects->empty() ? defects : nullptr;
  const ImageView img = known ? RepairDefects(view, *known, &bu.repaired) : view;

  // 1. Background and noise per tile (median and MAD: robust to stars and hot pixels).
  auto t0 = now();
  // Matched filter: a box of about the PSF's size (3x3 is 88% efficient for sigma 1.2 px).
  const double psf_guess = opt.psf_sigma_px > 0 ? opt.psf_sigma_px : 1.2;
  const int half = psf_guess <= 1.6 ? 1 : (psf_guess <= 2.8 ? 2 : 3);
  const BackgroundGrid& bg = bu.bg;
  EstimateBackground(img, opt.tile_px, half, &bu.bg_scratch, &bu.bg, opt.block_aware_noise);
  out->background_adu = bg.median_level;
  out->noise_adu = bg.median_sigma;
  out->block_artefact_ratio = bg.block_ratio;
  out->block_artefacts = bg.block_artefacts;
  if (diag) out->timing_ms["background"] = MsSince(t0);

  // 2. Threshold the box sum on its own measured local noise.
  t0 = now();
  ScratchVec<Run>& runs = bu.runs;
  ScratchVec<std::pair<int, int>>& dead_pixels = bu.dead_pixels;
  runs.clear();
  dead_pixels.clear();
  ThresholdRuns(img, view, bg, opt, half, known, caps, &bu.threshold, &runs, &dead_pixels, clamped);
  if (diag) out->timing_ms["threshold"] = MsSince(t0);

  // 3. Connected blobs.
  t0 = now();
  ConnectBlobs(runs, caps, &bu.blobs, clamped);
  ScratchVec<Blob>& blobs = bu.blobs.blobs;
  const BlobSet bs{runs, blobs, bu.blobs.blob_runs};
  if (diag) out->timing_ms["blobs"] = MsSince(t0);

  // 4. Peaks inside each blob.
  t0 = now();
  BlobPeaks& bp = bu.peaks;
  FindPeaks(img, bg, blobs, bs, caps, &bu.peak_search, &bp, clamped);

  // 5. Classify each peak: spikes, then PSF fits, the frame's PSF, interferers, stars.
  PixelMask& bad = bu.bad;
  bad.Reset(w, h);
  for (const auto& [x, y] : dead_pixels) bad.Set(x, y);
  if (known) {
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        if (known->at(x, y)) bad.Set(x, y);
      }
    }
  }
  const PeakShape& ps = bu.shape;
  ClassifySpikes(img, bg, opt, caps, diag, &bp, &bad, &bu.shape, &out->rejected, clamped);
  const size_t max_fits = 3 * static_cast<size_t>(max_stars);
  const int max_half_px = lim.grow ? 0 : (lim.max_fit_window_px - 1) / 2;
  FitCandidates(img, view, bg, opt, psf_guess, bp, ps, bad, max_fits, max_half_px, &bu.fits, clamped);
  const ScratchVec<Candidate>& cands = bu.fits.cands;
  const double psf = FramePsfSigma(cands, bp.peaks, opt.psf_sigma_px, psf_guess, &bu.bright, &out->psf_source);
  out->psf_sigma_px = psf;
  const double sharp_ratio = std::clamp(0.45 * DiagonalRatio(psf), 0.02, 0.3);
  ScratchVec<uint8_t>& blob_reported = bu.blob_reported;  // one track/streak rejection per blob
  blob_reported.assign(blobs.size(), 0);
  ScratchVec<StarDetection>& stars = bu.stars;  // at most one per candidate
  stars.clear();
  for (const Candidate& c : cands) {
    const Peak& pk = bp.peaks[c.peak];
    const Blob& b = blobs[pk.blob];
    const PsfFit& f = c.fit;
    Rejection rej;
    if (Interferer(c, pk, b, bs, psf, sharp_ratio, bg.SigmaAt(pk.x, pk.y), &rej)) {
      const bool per_blob = rej.reason == RejectReason::kCosmicRay || rej.reason == RejectReason::kStreak;
      if (!(per_blob && blob_reported[pk.blob])) {
        if (diag) rej.detail = RejectDetailName(rej.detail_code);
        PushCapped(&out->rejected, caps.rejections, rej, kClampRejections, clamped);
      }
      if (per_blob) blob_reported[pk.blob] = 1;
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
    stars.push_back(s);
  }
  std::sort(stars.begin(), stars.end(),
            [](const StarDetection& a, const StarDetection& b) { return a.flux_adu > b.flux_adu; });
  const size_t kept = std::min(stars.size(), static_cast<size_t>(max_stars));
  if (kept < stars.size()) *clamped |= kClampStars;
  out->stars.assign(stars.begin(), stars.begin() + static_cast<std::ptrdiff_t>(kept));

  // 6. Defective pixels in the report.
  ReportDefects(view, bg, opt, dead_pixels, known, caps, &out->rejected, clamped);
  if (diag) {
    out->timing_ms["centroid"] = MsSince(t0);
    out->timing_ms["total"] = MsSince(t_start);
  }
  return DetectStatus::kOk;
}

Detections Detect(const ImageView& view, const DetectOptions& opt, const DefectMap* defects) {
  opt.Check();
  // A workspace for this frame whose lists grow as needed: the results depend on no limit.
  DetectLimits limits;
  limits.max_width = std::max(view.width, 16);
  limits.max_height = std::max(view.height, 16);
  limits.max_detections = opt.max_stars;
  limits.min_tile_px = opt.tile_px;
  limits.grow = true;
  DetectWorkspace ws(limits);
  Detections out;
  const DetectStatus st = Detect(view, opt, defects, &ws, &out);
  switch (st) {
    case DetectStatus::kOk:
      return out;
    case DetectStatus::kImageTooSmall:
      throw InputError("Detect: image smaller than 16x16");
    case DetectStatus::kDefectMapSize:
      throw InputError("Detect: defect map size differs from the image");
    case DetectStatus::kSmearCameraSize:
      throw InputError("Detect: smear.camera size differs from the image");
    default:
      throw InputError(std::string("Detect: ") + DetectStatusName(st));
  }
}

}  // namespace ssiu
