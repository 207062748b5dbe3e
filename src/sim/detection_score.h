// Scores a detection result against a simulated frame's truth: recall by SNR, false detections,
// artefacts reported as stars, centroid errors. Used by `ssiu demo`, the tests and the benchmarks.
#pragma once

#include <vector>

#include "core/camera.h"
#include "detect/detect.h"
#include "sim/frame_sim.h"

namespace ssiu {

struct ScoreOptions {
  double match_radius_px = 2.0;  // a detection this close to a truth star is that star
  // Smeared frames: a star's image is a track of its smear length, so a star is "blended" when a
  // neighbour (above 5% of its flux) lies within 4 px plus the longer of the two smears, and a star
  // under a cosmic-ray track or a satellite streak (within 4 px plus its smear) is not counted either:
  // overlapping images are one blob, correctly merged or rejected, not a miss. Off: 4 px, tracks ignored.
  bool smear_aware = false;
  void Check() const;  // throws InputError
};

struct DetectionScore {
  int true_stars = 0;        // truth stars inside the frame
  int true_stars_snr10 = 0;  // ... with SNR >= 10, not blended with a neighbour
  int found_snr10 = 0;
  int found_total = 0;         // reported stars matched to a truth star
  int false_detections = 0;    // reported stars matching no truth star
  int artefacts_as_stars = 0;  // reported stars on an injected hot pixel / cosmic ray / streak
  int hot_pixels_as_stars = 0;
  double centroid_rms_px = 0;  // over matched, unsaturated stars with truth SNR >= 20
  int centroid_count = 0;
  std::vector<double> dx_px, dy_px;  // per matched clean star with SNR >= 20, unsaturated
  std::vector<int> truth_index;      // ... and its index in the truth's stars
  std::vector<int> det_index;        // ... and in the detections' stars
  std::vector<int> missed_index;     // truth indices of the counted SNR >= 10 stars not found

  double recall_snr10() const { return true_stars_snr10 ? double(found_snr10) / true_stars_snr10 : 0.0; }
  // Adds another frame's score: counts summed, centroid errors appended, RMS over both. The indices
  // appended are the other frame's, so they are meaningful only per frame.
  void Add(const DetectionScore& other);
};

DetectionScore ScoreDetections(const SimulatedFrame& truth, const Detections& det, const ScoreOptions& options);
DetectionScore ScoreDetections(const SimulatedFrame& truth, const Detections& det, double match_radius_px = 2.0);

// The detector's options for a frame simulated with `so` on `camera`: the simulator's gain and, when
// `give_rate`, the smear it drew (its rates and exposure) handed over as the unit's processor does
// from the gyros.
DetectOptions DetectOptionsForSimulation(const Camera& camera, const FrameSimOptions& so, bool give_rate);

}  // namespace ssiu
