#include "sim/detection_score.h"

#include <algorithm>
#include <cmath>

namespace ssiu {

DetectionScore ScoreDetections(const SimulatedFrame& truth, const Detections& det, double radius) {
  DetectionScore sc;
  const int w = truth.image.width, h = truth.image.height;
  auto inside = [&](double x, double y) { return x >= 2 && y >= 2 && x <= w - 3 && y <= h - 3; };
  // A truth star counts as "clean" when no other drawn star lies within 4 px (a blended pair is
  // correctly rejected or merged, not a miss).
  std::vector<bool> clean(truth.stars.size(), true);
  for (size_t i = 0; i < truth.stars.size(); ++i) {
    for (size_t k = 0; k < truth.stars.size(); ++k) {
      if (i != k && std::hypot(truth.stars[i].x_px - truth.stars[k].x_px, truth.stars[i].y_px - truth.stars[k].y_px) < 4.0 &&
          truth.stars[k].flux_e > 0.05 * truth.stars[i].flux_e) {
        clean[i] = false;
      }
    }
  }
  std::vector<bool> used(det.stars.size(), false);
  double sum2 = 0;
  for (size_t i = 0; i < truth.stars.size(); ++i) {
    const SimStar& t = truth.stars[i];
    if (!inside(t.x_px, t.y_px)) continue;
    ++sc.true_stars;
    int best = -1;
    double best_d = radius;
    for (size_t k = 0; k < det.stars.size(); ++k) {
      const double d = std::hypot(det.stars[k].x_px - t.x_px, det.stars[k].y_px - t.y_px);
      if (d < best_d) {
        best_d = d;
        best = static_cast<int>(k);
      }
    }
    const bool counted = t.snr >= 10 && clean[i];
    if (counted) ++sc.true_stars_snr10;
    if (best < 0) continue;
    used[best] = true;
    ++sc.found_total;
    if (counted) ++sc.found_snr10;
    if (t.snr >= 20 && !t.saturated && clean[i]) {
      const double dx = det.stars[best].x_px - t.x_px, dy = det.stars[best].y_px - t.y_px;
      sc.dx_px.push_back(dx);
      sc.dy_px.push_back(dy);
      sc.truth_index.push_back(static_cast<int>(i));
      sum2 += dx * dx + dy * dy;
      ++sc.centroid_count;
    }
  }
  // Also mark detections near any truth star (e.g. a faint one just outside the counted set).
  for (size_t k = 0; k < det.stars.size(); ++k) {
    if (used[k]) continue;
    for (const SimStar& t : truth.stars) {
      if (std::hypot(det.stars[k].x_px - t.x_px, det.stars[k].y_px - t.y_px) < radius) used[k] = true;
    }
  }
  for (size_t k = 0; k < det.stars.size(); ++k) {
    if (used[k]) continue;
    ++sc.false_detections;
    for (const SimArtefact& a : truth.artefacts) {
      if (a.type == "dead_pixel") continue;
      // Distance from the detection to the artefact (a point or a segment).
      const double px = det.stars[k].x_px, py = det.stars[k].y_px;
      const double vx = a.x1_px - a.x0_px, vy = a.y1_px - a.y0_px, l2 = vx * vx + vy * vy;
      const double t = l2 > 0 ? std::clamp(((px - a.x0_px) * vx + (py - a.y0_px) * vy) / l2, 0.0, 1.0) : 0.0;
      const double d = std::hypot(px - (a.x0_px + t * vx), py - (a.y0_px + t * vy));
      if (d < radius + 1) {
        ++sc.artefacts_as_stars;
        if (a.type == "hot_pixel") ++sc.hot_pixels_as_stars;
        break;
      }
    }
  }
  sc.centroid_rms_px = sc.centroid_count ? std::sqrt(sum2 / (2.0 * sc.centroid_count)) : 0.0;
  return sc;
}

}  // namespace ssiu
