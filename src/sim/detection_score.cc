#include "sim/detection_score.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/error.h"

namespace ssiu {
namespace {

// Distance from (x, y) to an artefact: a point, or a segment for a cosmic-ray track or a streak.
double DistanceToArtefactPx(double x, double y, const SimArtefact& a) {
  const double vx = a.x1_px - a.x0_px, vy = a.y1_px - a.y0_px, l2 = vx * vx + vy * vy;
  const double u = l2 > 0 ? std::clamp(((x - a.x0_px) * vx + (y - a.y0_px) * vy) / l2, 0.0, 1.0) : 0.0;
  return std::hypot(x - (a.x0_px + u * vx), y - (a.y0_px + u * vy));
}

}  // namespace

void ScoreOptions::Check() const {
  if (!(match_radius_px > 0) || !std::isfinite(match_radius_px)) {
    throw InputError("ScoreOptions: match_radius_px must be positive and finite");
  }
}

void DetectionScore::Add(const DetectionScore& o) {
  true_stars += o.true_stars;
  true_stars_snr10 += o.true_stars_snr10;
  found_snr10 += o.found_snr10;
  found_total += o.found_total;
  false_detections += o.false_detections;
  artefacts_as_stars += o.artefacts_as_stars;
  hot_pixels_as_stars += o.hot_pixels_as_stars;
  dx_px.insert(dx_px.end(), o.dx_px.begin(), o.dx_px.end());
  dy_px.insert(dy_px.end(), o.dy_px.begin(), o.dy_px.end());
  truth_index.insert(truth_index.end(), o.truth_index.begin(), o.truth_index.end());
  det_index.insert(det_index.end(), o.det_index.begin(), o.det_index.end());
  missed_index.insert(missed_index.end(), o.missed_index.begin(), o.missed_index.end());
  centroid_count = static_cast<int>(dx_px.size());
  double sum2 = 0;
  for (size_t m = 0; m < dx_px.size(); ++m) sum2 += dx_px[m] * dx_px[m] + dy_px[m] * dy_px[m];
  centroid_rms_px = centroid_count ? std::sqrt(sum2 / (2.0 * centroid_count)) : 0.0;
}

DetectionScore ScoreDetections(const SimulatedFrame& truth, const Detections& det, double match_radius_px) {
  ScoreOptions o;
  o.match_radius_px = match_radius_px;
  return ScoreDetections(truth, det, o);
}

DetectionScore ScoreDetections(const SimulatedFrame& truth, const Detections& det, const ScoreOptions& opt) {
  opt.Check();
  const double radius = opt.match_radius_px;
  DetectionScore sc;
  const int w = truth.image.width, h = truth.image.height;
  auto inside = [&](double x, double y) { return x >= 2 && y >= 2 && x <= w - 3 && y <= h - 3; };
  // A truth star counts as "clean" when no other drawn star lies within 4 px (a blended pair is
  // correctly rejected or merged, not a miss); smear-aware, 4 px plus the longer smear, and no track.
  std::vector<bool> clean(truth.stars.size(), true);
  for (size_t i = 0; i < truth.stars.size(); ++i) {
    const SimStar& t = truth.stars[i];
    for (size_t k = 0; k < truth.stars.size(); ++k) {
      const SimStar& n = truth.stars[k];
      const double blend_px = 4.0 + (opt.smear_aware ? std::max(t.smear_px, n.smear_px) : 0.0);
      if (i != k && std::hypot(t.x_px - n.x_px, t.y_px - n.y_px) < blend_px && n.flux_e > 0.05 * t.flux_e) {
        clean[i] = false;
      }
    }
    if (!opt.smear_aware) continue;
    // A star crossed by a cosmic-ray track or a streak goes down with it (rejected as part of that blob).
    for (const SimArtefact& a : truth.artefacts) {
      const bool track = a.type == "cosmic_ray" || a.type == "streak";
      if (track && DistanceToArtefactPx(t.x_px, t.y_px, a) < 4.0 + t.smear_px) clean[i] = false;
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
    if (best < 0) {
      if (counted) sc.missed_index.push_back(static_cast<int>(i));
      continue;
    }
    used[best] = true;
    ++sc.found_total;
    if (counted) ++sc.found_snr10;
    if (t.snr >= 20 && !t.saturated && clean[i]) {
      const double dx = det.stars[best].x_px - t.x_px, dy = det.stars[best].y_px - t.y_px;
      sc.dx_px.push_back(dx);
      sc.dy_px.push_back(dy);
      sc.truth_index.push_back(static_cast<int>(i));
      sc.det_index.push_back(best);
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
      if (DistanceToArtefactPx(det.stars[k].x_px, det.stars[k].y_px, a) < radius + 1) {
        ++sc.artefacts_as_stars;
        if (a.type == "hot_pixel") ++sc.hot_pixels_as_stars;
        break;
      }
    }
  }
  sc.centroid_rms_px = sc.centroid_count ? std::sqrt(sum2 / (2.0 * sc.centroid_count)) : 0.0;
  return sc;
}

DetectOptions DetectOptionsForSimulation(const Camera& camera, const FrameSimOptions& so, bool give_rate) {
  DetectOptions o;
  o.gain_e_per_adu = so.gain_e_per_adu;
  if (give_rate) {
    o.smear.rate_rad_s = Vec3(so.rate_x_dps, so.rate_y_dps, so.rate_z_dps) * kDegToRad;
    o.smear.exposure_s = so.exposure_s;
    o.smear.camera = camera;
  }
  return o;
}

}  // namespace ssiu
