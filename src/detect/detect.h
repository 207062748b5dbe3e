// Star detection: a frame -> background and noise, sub-pixel star centroids, rejected interferers.
//
//   Detections d = Detect(frame.image.view(), DetectOptions{}, &defect_map);
//
// Flight use (no heap after initialisation): a DetectWorkspace reserved once for the largest frame
// and the most detections, and a caller-owned Detections that each call clears and refills:
//
//   DetectLimits lim;  lim.max_width = 1024;  lim.max_height = 1024;  lim.diagnostics = false;
//   DetectWorkspace ws(lim);              // allocates here
//   Detections d;  ws.Reserve(&d);
//   DetectStatus st = Detect(view, options, nullptr, &ws, &d);   // no allocation, no exception
//
// Pipeline (docs/design.md): robust tiled background/noise (median, MAD; hot pixels and stars do not
// inflate it) -> defect-map pixels repaired -> matched (PSF-sized box) filter -> threshold on local
// noise -> connected blobs -> per-blob classification (hot pixel, cosmic ray, streak, extended, star)
// -> Gaussian-fit centroid (pixel-integrated Gaussian, weighted least squares; reaches the Cramer-Rao
// bound at high SNR) with saturated and defective pixels left out of the fit.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "core/arena.h"
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
  // A frame that shows JPEG's 8x8 blocks (docs/detection.md, "JPEG frames") gets its noise from the
  // lower tails of the pixels and box sums as well: the quantised blocks' spread, not only the core.
  bool block_aware_noise = true;
  // Motion during the exposure, from the gyros (inactive by default: the static detector). When
  // active, each star is fitted as the PSF smeared along its predicted path (detect/smear.h) and the
  // shape tests allow that smear, not more: cosmic rays and streaks that do not match stay rejected.
  ExpectedSmear smear;
  void Check() const;  // throws InputError naming the field
  // The first problem Check would report, without the "DetectOptions: " prefix and without checking
  // smear.camera (Camera::Check, done once where the camera is set up); nullptr when none. Allocates
  // nothing and does not throw.
  const char* Problem() const;
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
inline std::ostream& operator<<(std::ostream& os, RejectReason v) { return os << RejectReasonName(v); }

// The finer reason of some rejections (Rejection::detail as a code).
enum class RejectDetail { kNone, kOnSource, kBlendedPair, kSaturatedExtended, kElongated };
const char* RejectDetailName(RejectDetail d);  // "", "on_source", "blended_pair", ...
inline std::ostream& operator<<(std::ostream& os, RejectDetail v) { return os << RejectDetailName(v); }

struct Rejection {
  double x_px = 0, y_px = 0;
  RejectReason reason = RejectReason::kExtended;
  std::string detail;  // RejectDetailName(detail_code), e.g. "blended_pair"; "" without diagnostics
  double flux_adu = 0;
  RejectDetail detail_code = RejectDetail::kNone;
};

// Which limits of the workspace (DetectLimits) a call reached, as bits of Detections::clamped.
enum DetectClamp : unsigned {
  kClampStars = 1u << 0,        // more stars passed than max_stars / max_detections: the faintest dropped
  kClampRuns = 1u << 1,         // max_runs: sources further down the frame not found
  kClampBlobs = 1u << 7,        // max_blobs: sources further down the frame not found
  kClampPeaks = 1u << 2,        // max_peaks: later blobs' peaks dropped
  kClampBlobMaxima = 1u << 3,   // max_blob_maxima: a blob's fainter local maxima not considered
  kClampRejections = 1u << 4,   // max_rejections: the report of rejections is cut short
  kClampDeadPixels = 1u << 5,   // max_dead_pixels: further dead pixels neither masked nor reported
  kClampFitWindow = 1u << 6,    // max_fit_window_px: some PSF fits had a smaller window than asked
};

struct Detections {
  int width = 0, height = 0;
  double background_adu = 0;         // median of the tile backgrounds
  double noise_adu = 0;              // median of the tile noise sigmas
  // The frame's 8x8 block statistic (BlockArtefactRatio: ~1 uncompressed, above 1.05 JPEG blocks).
  double block_artefact_ratio = 1;
  bool block_artefacts = false;
  double psf_sigma_px = 0;           // PSF sigma used (estimated or given)
  // Where it came from (JSON "psf_source"): "given" (DetectOptions::psf_sigma_px: the flag or the camera's),
  // "measured" (the median of the bright isolated stars' fits), or "assumed": fewer than 3 such stars, so
  // the 1.2 px default, which the frame could not confirm.
  const char* psf_source = "assumed";
  // (ScratchVec: the flight core keeps its lists in the caller's memory, core/arena.h.)
  ScratchVec<StarDetection> stars;  // brightest first
  ScratchVec<Rejection> rejected;
  std::map<std::string, double> timing_ms;  // filled only with DetectLimits::diagnostics
  unsigned clamped = 0;                     // DetectClamp bits: the limits this call reached
};

// A static defect map: nonzero = defective pixel (hot, dead, or otherwise unusable).
struct DefectMap {
  int width = 0, height = 0;
  ScratchVec<uint8_t> mask;  // row-major; 0 good, 1 hot, 2 dead, 3 other (the flight core's in its arena)
  bool empty() const { return mask.empty(); }
  uint8_t at(int x, int y) const { return mask[static_cast<size_t>(y) * width + x]; }
};

Detections Detect(const ImageView& image, const DetectOptions& options = {}, const DefectMap* defects = nullptr);

// What Detect's sizes a workspace holds. Per-pixel buffers are sized by max_width x max_height; the
// lists by the counts below, which a call never grows past: it stops adding and sets a
// Detections::clamped bit instead (defaults: room for a 1024^2 star frame many times over).
struct DetectLimits {
  int max_width = 1024, max_height = 1024;
  int max_detections = 1000;  // stars output (DetectOptions::max_stars above this acts as this)
  int min_tile_px = 16;       // smallest DetectOptions::tile_px the background grids have room for
  int max_runs = 32768;         // above-threshold row runs (a star makes a few)
  int max_blobs = 8192;         // connected blobs of runs (a star, a hot pixel, a track: one each)
  int max_peaks = 8192;         // peaks kept over all blobs (at most 12 per blob)
  int max_blob_maxima = 4096;   // local maxima of one blob searched for peaks
  int max_rejections = 4096;    // rejected sources reported
  int max_dead_pixels = 4096;   // dead pixels masked and reported
  int max_fit_window_px = 64;   // side of a PSF-fit window (PSF sigma 1.2 px: 7; a smear adds its length)
  // Timing (Detections::timing_ms) and text (Rejection::detail) only when set: the flight path clears it.
  bool diagnostics = true;
  // Lists grow past their limits instead of clamping (Detect's one-call form only: results then do
  // not depend on the limits; allocation-free use leaves it false).
  bool grow = false;
  void Check() const;  // throws InputError naming the field
};

// Why a workspace call gave no detections (kOk: it ran; Detections::clamped tells of limits reached).
enum class DetectStatus {
  kOk,
  kBadOptions,        // DetectOptions::Problem() != nullptr
  kImageTooSmall,     // under 16 x 16, or no pixels
  kImageTooLarge,     // over DetectLimits::max_width x max_height
  kTileTooSmall,      // tile_px under DetectLimits::min_tile_px
  kDefectMapSize,     // defect map not the image's size
  kSmearCameraSize,   // smear.camera not the image's size
};
const char* DetectStatusName(DetectStatus s);  // "ok", "bad_options", ...
inline std::ostream& operator<<(std::ostream& os, DetectStatus v) { return os << DetectStatusName(v); }

// Every buffer Detect needs, reserved at construction for `limits` (allocates only there).
class DetectWorkspace {
 public:
  // limits.Check() (throws InputError). Every buffer comes from `mr` (the heap by default; the flight
  // core's arena, core/arena.h).
  explicit DetectWorkspace(const DetectLimits& limits,
                           std::pmr::memory_resource* mr = std::pmr::get_default_resource());
  ~DetectWorkspace();
  DetectWorkspace(DetectWorkspace&&) noexcept;
  DetectWorkspace& operator=(DetectWorkspace&&) noexcept;
  const DetectLimits& limits() const { return limits_; }
  // Gives `out` the capacity a call may fill (stars and rejections), so that no call grows it.
  void Reserve(Detections* out) const;
  // Heap bytes the workspace holds (its buffers' capacities), and those Reserve gives a Detections.
  size_t Bytes() const;
  size_t OutputBytes() const;

  struct Buffers;  // detect.cc

 private:
  DetectLimits limits_;
  ResourcePtr<Buffers> b_;
  friend DetectStatus Detect(const ImageView&, const DetectOptions&, const DefectMap*, DetectWorkspace*,
                             Detections*);
};

// Detect with a workspace: `out` is cleared (capacity kept) and refilled. No exceptions; with
// diagnostics off and `out` reserved (DetectWorkspace::Reserve), no heap allocation. Bad input is the
// status (then `out` is empty). The one implementation: Detect above is this with a local workspace
// (grow = true) and the statuses thrown as InputError.
DetectStatus Detect(const ImageView& image, const DetectOptions& options, const DefectMap* defects,
                    DetectWorkspace* workspace, Detections* out);

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
// Marks pixel (x, y) hot in *map, first made all good at width x height when it is empty (camera.json's
// known hot_pixels added to a map). InputError naming `where` for a pixel outside width x height or a map
// of another size. Detect takes an empty map as none.
void MarkHotPixel(int x, int y, int width, int height, DefectMap* map, const std::string& where = "hot pixel");
// The same for each [x, y] of `pixels` (camera.json's `hot_pixels`, CameraExtras).
void MarkHotPixels(const std::vector<std::array<int, 2>>& pixels, int width, int height, DefectMap* map,
                   const std::string& where = "hot_pixels");

}  // namespace ssiu
