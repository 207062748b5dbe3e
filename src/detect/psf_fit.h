// Internal to detect: sub-pixel centroid of one source by a weighted least-squares fit of a
// pixel-integrated circular Gaussian plus a local constant background.
#pragma once

#include <functional>

#include "core/image.h"

namespace ssiu {

struct PsfFitOptions {
  double sigma_guess_px = 1.2;
  double gain_e_per_adu = 0;  // > 0: shot noise enters the weights (then the fit is ~ML)
  double saturation_adu = 65535;
  bool fit = true;          // false: weighted moments only
  int max_iterations = 12;  // converged fits take 3-6; noise blobs would wander on
  // Expected motion smear (end minus start of the star's image over the exposure, px). Nonzero: the
  // model is the Gaussian averaged along that segment centred on (x, y), the window grows by the
  // smear, and elongation is measured against the smeared model's own shape (1 = as predicted).
  double smear_dx_px = 0, smear_dy_px = 0;
};

struct PsfFit {
  bool ok = false;
  double x_px = 0, y_px = 0;
  double flux_adu = 0, background_adu = 0, sigma_px = 0;
  double snr = 0;
  double x_sigma_px = 0, y_sigma_px = 0;
  double elongation = 1;  // sqrt of the ratio of the second-moment eigenvalues
  double major_sigma_px = 0;
  int iterations = 0;
};

// Fits the window of half-size r around (px, py). level / sigma_n: local background and noise
// (ADU). is_bad(x, y) marks pixels to leave out (defects, dead pixels); saturated pixels are left
// out too.
PsfFit FitPsf(const ImageView& img, int px, int py, int r, double level, double sigma_n, const PsfFitOptions& options,
              const std::function<bool(int, int)>& is_bad);

}  // namespace ssiu
