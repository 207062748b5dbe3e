// The frame set discovery works on (SolveFrameSet: every frame solved with the camera as given, its
// matched stars with their residuals and stamps) and the field laws the causes share (vignetting,
// the squared field radius).
#include "discover/discover_frames.h"

#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/distributions/normal.hpp>
#include <cmath>
#include <limits>

#include "core/astrometry.h"
#include "core/error.h"
#include "core/stats.h"
#include "core/types.h"
#include "discover/discover_frames_internal.h"
#include "discover/discovery_json.h"


namespace ssiu {

SolvedFrameSet SolveFrameSet(const StarIdentifier& id, const std::vector<ImageView>& images,
                             const std::vector<std::string>& names, const Camera& camera, const SolveOptions& options,
                             const DefectMap* known_defects) {
  if (known_defects && !known_defects->empty() &&
      (known_defects->width != camera.width || known_defects->height != camera.height ||
       known_defects->mask.size() != static_cast<size_t>(camera.width) * camera.height)) {
    throw InputError("defect map", "size differs from the camera's width/height");
  }
  for (size_t i = 0; i < images.size(); ++i) {
    if (images[i].width != camera.width || images[i].height != camera.height) {
      throw InputError(i < names.size() ? names[i] : "frame", "frame size differs from the camera's width/height");
    }
  }
  // The camera is what discovery tests: each frame's matches are taken with it as given, not with a
  // focal length refitted frame by frame.
  SolveOptions so = options;
  so.identify.refine_focal_p = 0;
  SolvedFrameSet set;
  set.names = names;
  set.width = camera.width, set.height = camera.height;
  constexpr int kStampHalf = 5;  // 11 x 11: +-3 sigma of a 1.8 px PSF
  for (size_t i = 0; i < images.size(); ++i) {
    const ImageView& img = images[i];
    const SolveResult r = SolveFrame(id, img, camera, so, known_defects);
    set.status.push_back(r.status);
    std::vector<PixelSource> spikes;
    for (const auto& rej : r.detections.rejected) {
      if (rej.reason == RejectReason::kHotPixel) {
        spikes.push_back(
            {static_cast<int>(std::lround(rej.x_px)), static_cast<int>(std::lround(rej.y_px)), rej.flux_adu});
      }
    }
    set.spikes.push_back(spikes);
    if (r.status != SolveStatus::kSolved) continue;
    const int f = static_cast<int>(set.q.size());
    set.q.push_back(r.attitude.q_inertial_from_sensor);
    set.solved_index.push_back(static_cast<int>(i));
    set.background_adu.push_back(r.detections.background_adu);
    set.noise_adu.push_back(r.detections.noise_adu);
    const auto& dets = r.detections.stars;
    for (const auto& m : r.identification.matches) {
      FrameStar s;
      s.frame = f;
      s.x_px = m.x_px;
      s.y_px = m.y_px;
      s.mag = m.mag;
      s.r_inertial = m.r_inertial;
      s.noise_adu = r.detections.noise_adu;
      if (m.centroid >= 0 && m.centroid < static_cast<int>(r.centroids.size())) {
        s.flux = r.centroids[m.centroid].flux;
        s.sigma_px = r.centroids[m.centroid].sigma_px > 0 ? r.centroids[m.centroid].sigma_px : 0.1;
      }
      if (m.centroid >= 0 && m.centroid < static_cast<int>(dets.size())) {
        const StarDetection& det = dets[m.centroid];  // centroids are the detections in order
        s.psf_sigma_px = det.sigma_px;
        s.saturated = det.saturated;
        // Stamp for the PSF analysis: unsaturated, inside the image, no other source within it.
        const int cx = static_cast<int>(std::lround(det.x_px)), cy = static_cast<int>(std::lround(det.y_px));
        const int x0 = cx - kStampHalf, y0 = cy - kStampHalf, wd = 2 * kStampHalf + 1, guard = kStampHalf + 2;
        bool ok = !det.saturated && x0 >= 0 && y0 >= 0 && x0 + wd <= img.width && y0 + wd <= img.height;
        for (size_t k = 0; ok && k < dets.size(); ++k) {
          ok = static_cast<int>(k) == m.centroid || std::abs(dets[k].x_px - det.x_px) > guard ||
               std::abs(dets[k].y_px - det.y_px) > guard;
        }
        for (const auto& rej : r.detections.rejected) {
          if (ok && rej.reason != RejectReason::kHotPixel) {
            ok = std::abs(rej.x_px - det.x_px) > guard || std::abs(rej.y_px - det.y_px) > guard;
          }
        }
        if (ok) {
          s.stamp_x0 = x0, s.stamp_y0 = y0, s.stamp_half = kStampHalf;
          s.stamp.resize(static_cast<size_t>(wd) * wd);
          for (int y = 0; y < wd; ++y) {
            for (int x = 0; x < wd; ++x) {
              const bool bad = (known_defects && !known_defects->empty() && known_defects->at(x0 + x, y0 + y)) ||
                               std::any_of(spikes.begin(), spikes.end(),
                                           [&](const PixelSource& p) { return p.x == x0 + x && p.y == y0 + y; });
              s.stamp[static_cast<size_t>(y) * wd + x] =
                  bad ? std::numeric_limits<float>::quiet_NaN() : static_cast<float>(img.at(x0 + x, y0 + y));
            }
          }
        }
      }
      set.stars.push_back(s);
    }
  }
  return set;
}

double discover_internal::FitVignettingLaw(const std::vector<double>& vu, const std::vector<double>& vy,
                                           double* sigma) {
  // y = c + ln(1 - v u) by a 1-D search over v (c is the mean for each v); sigma from the curvature of
  // the sum of squares with the residual scale.
  auto ss_of = [&](double v) {
    const int n = static_cast<int>(vu.size());
    double c = 0;
    for (int i = 0; i < n; ++i) c += (vy[i] - std::log(1 - v * vu[i])) / n;
    double ss = 0;
    for (int i = 0; i < n; ++i) ss += std::pow(vy[i] - c - std::log(1 - v * vu[i]), 2);
    return ss;
  };
  double lo = -1.0, hi = 0.95;
  for (int it = 0; it < 100; ++it) {  // golden section
    const double a = hi - 0.618 * (hi - lo), b = lo + 0.618 * (hi - lo);
    (ss_of(a) < ss_of(b) ? hi : lo) = ss_of(a) < ss_of(b) ? b : a;
  }
  const double v = 0.5 * (lo + hi), h = 1e-3;
  if (sigma) {
    const double curv = (ss_of(v + h) - 2 * ss_of(v) + ss_of(v - h)) / (h * h);
    const double s2v = ss_of(v) / std::max<size_t>(1, vu.size() - 2);
    *sigma = curv > 0 ? std::sqrt(2 * s2v / curv) : 1.0;
  }
  return v;
}

}  // namespace ssiu
