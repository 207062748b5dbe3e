// Scores a detection result against a simulated frame's truth: recall by SNR, false detections,
// artefacts reported as stars, centroid errors. Used by `ssiu demo`, the tests and the benchmarks.
#pragma once

#include <vector>

#include "detect/detect.h"
#include "sim/frame_sim.h"

namespace ssiu {

struct DetectionScore {
  int true_stars = 0;            // truth stars inside the frame
  int true_stars_snr10 = 0;      // ... with SNR >= 10, not blended with a neighbour
  int found_snr10 = 0;
  int found_total = 0;           // reported stars matched to a truth star
  int false_detections = 0;      // reported stars matching no truth star
  int artefacts_as_stars = 0;    // reported stars on an injected hot pixel / cosmic ray / streak
  int hot_pixels_as_stars = 0;
  double centroid_rms_px = 0;    // over matched, unsaturated stars with truth SNR >= 20
  int centroid_count = 0;
  std::vector<double> dx_px, dy_px;  // per matched clean star with SNR >= 20, unsaturated
  std::vector<int> truth_index;      // ... and its index in the truth's stars
};

DetectionScore ScoreDetections(const SimulatedFrame& truth, const Detections& det, double match_radius_px = 2.0);

}  // namespace ssiu
