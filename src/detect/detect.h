// Star detection: a frame -> background and noise, sub-pixel star centroids, rejected interferers.
//
//   Detections d = Detect(frame.image.view(), DetectOptions{}, &defect_map);
//
// Pipeline (docs/design.md): robust tiled background/noise (median, MAD; hot pixels and stars do not
// inflate it) -> defect-map pixels repaired -> matched (PSF-sized box) filter -> threshold on local
// noise -> connected blobs -> per-blob classification (hot pixel, cosmic ray, streak, extended, star)
// -> Gaussian-fit centroid (pixel-integrated Gaussian, weighted least squares; reaches the Cramer-Rao
// bound at high SNR) with saturated and defective pixels left out of the fit.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/image.h"
#include "detect/smear.h"

namespace ssiu {

struct DetectOptions {
  double threshold_sigma = 5.0;   // detection threshold on the matched-filter output, in its noise sigma
  double min_snr = 5.0;           // stars below this estimated SNR are dropped
  int tile_px = 64;               // background/noise tile size
  double psf_sigma_px = 0.0;      // expected PSF sigma; 0 = estimate from the frame's stars
  double gain_e_per_adu = 0.0;    // for shot-noise weights and SNR; 0 = unknown (background noise only)
  double saturation_adu = 65535;  // full-scale value; pixels at or above it are saturated
  double dead_sigma = 8.0;        // a pixel this many noise sigmas below background is dead
  int max_stars = 1000;           // keep at most this many (brightest first)
  bool reject_hot_pixels = true;  // on-the-fly single-pixel spike rejection
  bool fit_gaussian = true;       // refine centroids by a Gaussian fit (else: weighted moments)
  // Motion during the exposure, from the gyros (inactive by default: the static detector). When
  // active, each star is fitted as the PSF smeared along its predicted path (detect/smear.h) and the
  // shape tests allow that smear, not more: cosmic rays and streaks that do not match stay rejected.
  ExpectedSmear smear;
  void Check() const;  // throws InputError naming the field
};

struct StarDetection {
  double x_px = 0, y_px = 0;  // centroid, pixel (0,0) = centre of the top-left pixel
  double flux_adu = 0;        // background-subtracted total flux
  double peak_adu = 0;        // brightest pixel above background
  double snr = 0;             // flux / its 1-sigma noise
  int npix = 0;               // pixels above threshold in the blob
  bool saturated = false;
  double sigma_px = 0;                    // fitted Gaussian sigma (0 if not fitted)
  double x_sigma_px = 0, y_sigma_px = 0;  // centroid 1-sigma from the fit's covariance
};

enum class RejectReason { kHotPixel, kDeadPixel, kDefectMap, kCosmicRay, kStreak, kExtended };
const char* RejectReasonName(RejectReason r);  // "hot_pixel", "dead_pixel", ...

struct Rejection {
  double x_px = 0, y_px = 0;
  RejectReason reason = RejectReason::kExtended;
  std::string detail;  // e.g. "blended_pair", "saturated_extended"
  double flux_adu = 0;
};

struct Detections {
  int width = 0, height = 0;
  double background_adu = 0;         // median of the tile backgrounds
  double noise_adu = 0;              // median of the tile noise sigmas
  double psf_sigma_px = 0;           // PSF sigma used (estimated or given)
  std::vector<StarDetection> stars;  // brightest first
  std::vector<Rejection> rejected;
  std::map<std::string, double> timing_ms;
};

// A static defect map: nonzero = defective pixel (hot, dead, or otherwise unusable).
struct DefectMap {
  int width = 0, height = 0;
  std::vector<uint8_t> mask;  // row-major; 0 good, 1 hot, 2 dead, 3 other
  bool empty() const { return mask.empty(); }
  uint8_t at(int x, int y) const { return mask[static_cast<size_t>(y) * width + x]; }
};

Detections Detect(const ImageView& image, const DetectOptions& options = {}, const DefectMap* defects = nullptr);

// Builds a defect map from dark or median frames: pixels that stand out from their local
// background by more than `sigma` noise sigmas in most of the frames (hot: above, dead: below).
struct DefectMapOptions {
  double sigma = 6.0;
  int tile_px = 64;
  void Check() const;
};
DefectMap BuildDefectMap(const std::vector<ImageView>& frames, const DefectMapOptions& options = {});
// PNG I/O of the map: 0 good, 255 hot, 128 dead. InputError naming the file for a bad map.
DefectMap LoadDefectMap(const std::string& path);
void SaveDefectMap(const std::string& path, const DefectMap& map);

}  // namespace ssiu
