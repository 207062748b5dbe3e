// Recall and centroid error of a detection on a smeared simulated frame. As ScoreDetections
// (sim/detection_score.h), but a star counts as clean only when no other drawn star (above 5% of its
// flux) lies within 4 px plus the longer of the two smears: smeared images that overlap along the
// path are one blob, correctly merged or rejected, not a miss. Nor is a star under a cosmic-ray track
// or a streak.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "detect/detect.h"
#include "sim/frame_sim.h"

namespace ssiu::testing {

struct SmearScore {
  int true10 = 0, found10 = 0;       // clean stars of truth SNR >= 10 inside the frame, and those found
  std::vector<double> dx_px, dy_px;  // centroid errors of found clean unsaturated stars of SNR >= 20
  std::vector<int> truth_index, det_index;
};

inline SmearScore ScoreSmeared(const SimulatedFrame& f, const Detections& d, double radius_px = 2.0) {
  SmearScore sc;
  const int w = f.image.width, h = f.image.height;
  for (size_t i = 0; i < f.stars.size(); ++i) {
    const SimStar& t = f.stars[i];
    if (t.x_px < 2 || t.y_px < 2 || t.x_px > w - 3 || t.y_px > h - 3 || t.snr < 10) continue;
    bool clean = true;
    for (size_t k = 0; k < f.stars.size() && clean; ++k) {
      const SimStar& o = f.stars[k];
      clean = k == i || o.flux_e <= 0.05 * t.flux_e ||
              std::hypot(o.x_px - t.x_px, o.y_px - t.y_px) >= 4.0 + std::max(t.smear_px, o.smear_px);
    }
    // A star crossed by a cosmic-ray track or a satellite streak goes down with it (rejected as part
    // of that blob): not a miss either.
    for (const SimArtefact& a : f.artefacts) {
      if (a.type != "cosmic_ray" && a.type != "streak") continue;
      const double vx = a.x1_px - a.x0_px, vy = a.y1_px - a.y0_px, l2 = vx * vx + vy * vy;
      const double u = l2 > 0 ? std::clamp(((t.x_px - a.x0_px) * vx + (t.y_px - a.y0_px) * vy) / l2, 0.0, 1.0) : 0.0;
      if (std::hypot(t.x_px - (a.x0_px + u * vx), t.y_px - (a.y0_px + u * vy)) < 4.0 + t.smear_px) clean = false;
    }
    if (!clean) continue;
    ++sc.true10;
    int best = -1;
    double best_d = radius_px;
    for (size_t k = 0; k < d.stars.size(); ++k) {
      const double dist = std::hypot(d.stars[k].x_px - t.x_px, d.stars[k].y_px - t.y_px);
      if (dist < best_d) {
        best_d = dist;
        best = static_cast<int>(k);
      }
    }
    if (best < 0) continue;
    ++sc.found10;
    if (t.snr >= 20 && !t.saturated) {
      sc.dx_px.push_back(d.stars[best].x_px - t.x_px);
      sc.dy_px.push_back(d.stars[best].y_px - t.y_px);
      sc.truth_index.push_back(static_cast<int>(i));
      sc.det_index.push_back(best);
    }
  }
  return sc;
}

}  // namespace ssiu::testing
