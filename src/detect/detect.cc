#include "detect/detect.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include <Eigen/Dense>

#include "detect/background.h"
#include "detect/psf_fit.h"

namespace ssiu {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

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

// Expected ratio of the diagonal neighbours to the peak pixel for a pixel-centred Gaussian of
// sigma s: the smallest neighbour ratio of a real star (used to call a spike sharper than the PSF).
double DiagonalRatio(double s) {
  const double k = 1.0 / (std::sqrt(2.0) * s);
  const double f0 = std::erf(0.5 * k);
  const double f1 = 0.5 * (std::erf(1.5 * k) - std::erf(0.5 * k));
  const double r = f1 / f0;
  return r * r;
}

}  // namespace

const char* RejectReasonName(RejectReason r) {
  switch (r) {
    case RejectReason::kHotPixel: return "hot_pixel";
    case RejectReason::kDeadPixel: return "dead_pixel";
    case RejectReason::kDefectMap: return "defect_map";
    case RejectReason::kCosmicRay: return "cosmic_ray";
    case RejectReason::kStreak: return "streak";
    case RejectReason::kExtended: return "extended";
  }
  return "unknown";
}

void DetectOptions::Check() const {
  auto need = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("DetectOptions: ") + what);
  };
  need(std::isfinite(threshold_sigma) && threshold_sigma >= 2 && threshold_sigma <= 100, "threshold_sigma must be in [2, 100]");
  need(std::isfinite(min_snr) && min_snr >= 0, "min_snr must be >= 0");
  need(tile_px >= 8 && tile_px <= 1024, "tile_px must be in [8, 1024]");
  need(std::isfinite(psf_sigma_px) && psf_sigma_px >= 0 && psf_sigma_px < 50, "psf_sigma_px must be in [0, 50)");
  need(std::isfinite(gain_e_per_adu) && gain_e_per_adu >= 0, "gain_e_per_adu must be >= 0");
  need(std::isfinite(saturation_adu) && saturation_adu > 0, "saturation_adu must be > 0");
  need(std::isfinite(dead_sigma) && dead_sigma > 2, "dead_sigma must be > 2");
  need(max_stars > 0, "max_stars must be > 0");
}

Detections Detect(const ImageView& view, const DetectOptions& opt, const DefectMap* defects) {
  opt.Check();
  const auto t_start = Clock::now();
  const int w = view.width, h = view.height;
  if (w < 16 || h < 16 || view.data == nullptr) throw std::invalid_argument("Detect: image smaller than 16x16");
  if (defects && !defects->empty() && (defects->width != w || defects->height != h)) {
    throw std::invalid_argument("Detect: defect map size differs from the image");
  }
  Detections out;
  out.width = w;
  out.height = h;

  // Defect-map pixels are repaired (median of good neighbours) in a working copy so that they make
  // no detections and do not bias the background; the fit leaves them out.
  std::vector<uint16_t> repaired;
  ImageView img = view;
  const bool have_defects = defects && !defects->empty();
  if (have_defects) {
    repaired.resize(static_cast<size_t>(w) * h);
    for (int y = 0; y < h; ++y) std::copy(view.row(y), view.row(y) + w, &repaired[static_cast<size_t>(y) * w]);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        if (!defects->at(x, y)) continue;
        std::array<uint16_t, 8> nb;
        int n = 0;
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if ((dx || dy) && xx >= 0 && yy >= 0 && xx < w && yy < h && !defects->at(xx, yy)) nb[n++] = view.at(xx, yy);
          }
        }
        if (n > 0) {
          std::nth_element(nb.begin(), nb.begin() + n / 2, nb.begin() + n);
          repaired[static_cast<size_t>(y) * w + x] = nb[n / 2];
        }
      }
    }
    img = ImageView{w, h, w, repaired.data()};
  }

  // 1. Background and noise per tile (median and MAD: robust to stars and hot pixels).
  auto t0 = Clock::now();
  const BackgroundGrid bg = EstimateBackground(img, opt.tile_px);
  out.background_adu = bg.median_level;
  out.noise_adu = bg.median_sigma;
  out.timing_ms["background"] = MsSince(t0);

  // 2. Matched filter (box of about the PSF's size) and threshold on local noise: a b x b box sum
  //    has noise b * sigma for independent pixels.
  t0 = Clock::now();
  const double psf_guess = opt.psf_sigma_px > 0 ? opt.psf_sigma_px : 1.2;
  const int half = psf_guess <= 1.6 ? 1 : (psf_guess <= 2.8 ? 2 : 3);
  const int box = 2 * half + 1;
  std::vector<Run> runs;
  std::vector<std::pair<int, int>> dead_pixels;
  {
    std::vector<int32_t> colsum(static_cast<size_t>(w), 0);
    std::vector<float> thr_row(static_cast<size_t>(w)), low_row(static_cast<size_t>(w));
    // Column sums of the first box rows; then slide down.
    for (int y = 0; y < box - 1; ++y) {
      const uint16_t* r = img.row(y);
      for (int x = 0; x < w; ++x) colsum[x] += r[x];
    }
    std::vector<int32_t> boxrow(static_cast<size_t>(w), 0);
    for (int yc = 0; yc < h; ++yc) {
      // Raw-pixel test for dead pixels on every row.
      bg.RowLevels(yc, &low_row, -opt.dead_sigma, 1.0);
      const uint16_t* raw = view.row(yc);
      for (int x = 0; x < w; ++x) {
        if (raw[x] < low_row[x] && !(have_defects && defects->at(x, yc))) dead_pixels.emplace_back(x, yc);
      }
      if (yc < half || yc >= h - half) continue;
      const int ylast = yc + half;
      const uint16_t* add = img.row(ylast);
      for (int x = 0; x < w; ++x) colsum[x] += add[x];
      // Horizontal box sum of the column sums.
      for (int x = half; x < w - half; ++x) {
        int32_t s = 0;
        for (int k = -half; k <= half; ++k) s += colsum[x + k];
        boxrow[x] = s;
      }
      bg.RowLevels(yc, &thr_row, opt.threshold_sigma / box, static_cast<double>(box * box));
      int x = half;
      while (x < w - half) {
        if (boxrow[x] > thr_row[x]) {
          const int xs = x;
          while (x < w - half && boxrow[x] > thr_row[x]) ++x;
          runs.push_back({yc, xs, x - 1, -1});
        } else {
          ++x;
        }
      }
      const uint16_t* sub = img.row(yc - half);
      for (int xx = 0; xx < w; ++xx) colsum[xx] -= sub[xx];
    }
  }
  out.timing_ms["threshold"] = MsSince(t0);

  // 3. Connected blobs of runs (8-connectivity), union-find over runs of adjacent rows.
  t0 = Clock::now();
  std::vector<int> parent(runs.size());
  std::iota(parent.begin(), parent.end(), 0);
  {
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
  }
  std::vector<Blob> blobs;
  {
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
      // Peak of the raw image inside the blob (3x3-smoothed score to be robust to noise).
      for (int x = r.x0; x <= r.x1; ++x) {
        int64_t s = 0;
        for (int dy = -1; dy <= 1; ++dy) {
          const int yy = std::clamp(r.y + dy, 0, h - 1);
          for (int dx = -1; dx <= 1; ++dx) s += img.at(std::clamp(x + dx, 0, w - 1), yy);
        }
        s = s * 16 + img.at(x, r.y);  // tie-break on the centre pixel
        if (s > b.peak_score) {
          b.peak_score = s;
          b.peak_x = x;
          b.peak_y = r.y;
        }
      }
    }
  }
  out.timing_ms["blobs"] = MsSince(t0);

  // 4. Classify and centroid every blob.
  t0 = Clock::now();
  const double sat = opt.saturation_adu;
  auto is_bad = [&](int x, int y) {
    return (have_defects && defects->at(x, y)) ||
           std::binary_search(dead_pixels.begin(), dead_pixels.end(), std::make_pair(x, y),
                              [](const std::pair<int, int>& a, const std::pair<int, int>& b) {
                                return a.second != b.second ? a.second < b.second : a.first < b.first;
                              });
  };
  struct Candidate {
    size_t blob;
    PsfFit fit;
    double peak_above, min_dir_ratio;
    int nsat;
    bool sharp_single;
  };
  std::vector<Candidate> cands;
  cands.reserve(blobs.size());
  for (size_t bi = 0; bi < blobs.size(); ++bi) {
    const Blob& b = blobs[bi];
    const int px = b.peak_x, py = b.peak_y;
    const double level = bg.LevelAt(px, py), sigma_n = bg.SigmaAt(px, py);
    // Brightest raw pixel near the filtered peak.
    int mx = px, my = py;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int xx = px + dx, yy = py + dy;
        if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
        if (img.at(xx, yy) > img.at(mx, my)) {
          mx = xx;
          my = yy;
        }
      }
    }
    const double p = img.at(mx, my) - level;
    auto nb = [&](int dx, int dy) {
      const int xx = std::clamp(mx + dx, 0, w - 1), yy = std::clamp(my + dy, 0, h - 1);
      return img.at(xx, yy) - level;
    };
    // Mean of opposite neighbours in each of four directions, relative to the peak: a star
    // spreads in every direction, a hot pixel in none, a cosmic-ray track only along itself.
    const double dirs[4] = {0.5 * (nb(-1, 0) + nb(1, 0)), 0.5 * (nb(0, -1) + nb(0, 1)),
                            0.5 * (nb(-1, -1) + nb(1, 1)), 0.5 * (nb(-1, 1) + nb(1, -1))};
    const double dmax = *std::max_element(dirs, dirs + 4), dmin = *std::min_element(dirs, dirs + 4);
    Candidate c;
    c.blob = bi;
    c.peak_above = p;
    c.min_dir_ratio = p > 0 ? dmin / p : 1.0;
    c.nsat = 0;
    for (int y = std::max(0, b.y0 - 1); y <= std::min(h - 1, b.y1 + 1); ++y) {
      for (int x = std::max(0, b.x0 - 1); x <= std::min(w - 1, b.x1 + 1); ++x) c.nsat += view.at(x, y) >= sat;
    }
    // A single-pixel spike: no direction carries a significant share of the peak.
    c.sharp_single = c.nsat == 0 && p > 0 && dmax < 0.2 * p && dmax < p - 3 * sigma_n;
    if (c.sharp_single && opt.reject_hot_pixels) {
      out.rejected.push_back({static_cast<double>(mx), static_cast<double>(my), RejectReason::kHotPixel, "", p});
      continue;
    }
    PsfFitOptions fo;
    fo.sigma_guess_px = psf_guess;
    fo.gain_e_per_adu = opt.gain_e_per_adu;
    fo.saturation_adu = sat;
    fo.fit = opt.fit_gaussian;
    const int r = std::max(3, static_cast<int>(std::ceil(3 * psf_guess)));
    c.fit = FitPsf(img, mx, my, r, level, sigma_n, fo, is_bad);
    cands.push_back(c);
  }

  // The frame's PSF width: median fitted sigma of bright, unsaturated, compact sources (or as given).
  double psf = opt.psf_sigma_px;
  if (psf <= 0) {
    std::vector<double> s;
    for (const Candidate& c : cands) {
      if (c.fit.ok && c.nsat == 0 && c.fit.snr > 20 && c.min_dir_ratio > 0.15) s.push_back(c.fit.sigma_px);
    }
    if (s.size() >= 3) {
      std::nth_element(s.begin(), s.begin() + s.size() / 2, s.end());
      psf = s[s.size() / 2];
    } else {
      psf = psf_guess;
    }
  }
  out.psf_sigma_px = psf;
  const double sharp_ratio = std::clamp(0.45 * DiagonalRatio(psf), 0.06, 0.3);

  for (const Candidate& c : cands) {
    const Blob& b = blobs[c.blob];
    const PsfFit& f = c.fit;
    const double sigma_n = bg.SigmaAt(b.peak_x, b.peak_y);
    // Shape of the blob from second moments of the thresholded region (streaks, extended objects).
    const double ext_x = b.x1 - b.x0 + 1, ext_y = b.y1 - b.y0 + 1;
    const double length = std::hypot(ext_x, ext_y);
    const double cx = f.ok ? f.x_px : b.peak_x, cy = f.ok ? f.y_px : b.peak_y;
    Rejection rej;
    rej.x_px = cx;
    rej.y_px = cy;
    rej.flux_adu = f.flux_adu;
    bool reject = false;
    const bool significant_sharp = c.min_dir_ratio < sharp_ratio && c.peak_above * (sharp_ratio - c.min_dir_ratio) > 2.0 * sigma_n;
    if (c.nsat == 0 && significant_sharp) {
      // Sharper than the PSF across at least one direction: charge deposited in the pixels, not
      // imaged through the optics.
      rej.reason = b.npix <= 2 && length < 3 ? RejectReason::kHotPixel : RejectReason::kCosmicRay;
      reject = true;
    } else if (f.ok && f.elongation > 2.5 && f.major_sigma_px > 3 * psf && length > 10 * psf) {
      rej.reason = RejectReason::kStreak;
      reject = true;
    } else if (c.nsat == 0 && length > 10 * psf + 6 && b.npix > 40 * psf * psf) {
      rej.reason = RejectReason::kStreak;
      reject = true;
    } else if (c.nsat > 0 && c.nsat > 400) {
      rej.reason = RejectReason::kExtended;
      rej.detail = "saturated_extended";
      reject = true;
    } else if (c.nsat == 0 && f.ok && f.sigma_px > 2.0 * psf + 0.3 && f.snr > 10) {
      rej.reason = RejectReason::kExtended;
      reject = true;
    } else if (c.nsat == 0 && f.ok && f.blended) {
      rej.reason = RejectReason::kExtended;
      rej.detail = "blended_pair";
      reject = true;
    } else if (c.nsat == 0 && f.ok && f.elongation > 1.8 && f.snr > 30) {
      rej.reason = RejectReason::kExtended;
      rej.detail = "elongated";
      reject = true;
    }
    if (reject) {
      out.rejected.push_back(rej);
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

  // Dead pixels and defect-map pixels that would otherwise have looked like sources.
  const size_t kMaxReported = 2000;
  for (const auto& [x, y] : dead_pixels) {
    if (out.rejected.size() >= kMaxReported) break;
    out.rejected.push_back({static_cast<double>(x), static_cast<double>(y), RejectReason::kDeadPixel, "", 0});
  }
  if (have_defects) {
    for (int y = 0; y < h && out.rejected.size() < kMaxReported; ++y) {
      for (int x = 0; x < w; ++x) {
        if (!defects->at(x, y)) continue;
        const double above = view.at(x, y) - bg.LevelAt(x, y);
        if (above > opt.threshold_sigma * bg.SigmaAt(x, y)) {
          out.rejected.push_back({static_cast<double>(x), static_cast<double>(y), RejectReason::kDefectMap, "", above});
        }
      }
    }
  }
  out.timing_ms["centroid"] = MsSince(t0);
  out.timing_ms["total"] = MsSince(t_start);
  return out;
}

}  // namespace ssiu
