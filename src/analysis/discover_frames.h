// Model discrepancy of star frames (`ssiu discover frames`, docs/discrepancy.md): solve every frame,
// then compare what the camera model predicts with what was measured, name the cause from the fixed
// vocabulary (conventions.md), fit the extended camera and measure the gain on frames the fit did
// not see.
//
// Geometry: the matched stars' pixel positions against the catalog directions projected with the
// nominal camera. The base model has one small rotation per frame (the solved attitude refined
// with the nominal focal length). Candidates add focal_length (f), principal_point (cx, cy) or
// lens_distortion (k1), fitted jointly with the rotations by Gauss-Newton, weighted by the
// centroid sigmas; each is a Wald chi^2 against the base with the variance of the fullest model's
// residuals. Photometry: vignetting = ln(flux) + 0.4 ln(10) V regressed on (r / r_corner)^2
// (the simulator's law 1 - v (r/r_corner)^2). A candidate is significant when p < alpha / 4;
// the largest BIC gain among the significant ones is named.
// Gain: the camera fitted on the even frames is scored on the odd ones (rotations refitted there
// with the camera held) and vice versa; residual RMS with the nominal and with the fitted camera.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "core/camera.h"
#include "core/image.h"
#include "core/json.h"

namespace ssiu {

struct FrameStar {
  int frame = 0;
  double x_px = 0, y_px = 0, sigma_px = 0.1, flux = 0, mag = 0;
  double psf_sigma_px = 0;  // fitted Gaussian sigma of the spot (0 if not fitted)
  Vec3 r_inertial = Vec3::UnitZ();
};

struct SolvedFrameSet {
  std::vector<std::string> names;
  std::vector<std::string> status;  // per input frame
  std::vector<Quat> q;              // per solved frame (index = FrameStar::frame)
  std::vector<int> solved_index;    // input frame of each solved frame
  std::vector<FrameStar> stars;
  std::vector<double> background_adu, noise_adu;  // per solved frame (detector's tile medians)
};

// Solves each image (SolveFrame) and collects the identified stars.
SolvedFrameSet SolveFrameSet(const StarIdentifier& id, const std::vector<ImageView>& images,
                             const std::vector<std::string>& names, const Camera& camera, const SolveOptions& options);

struct FrameDiscoverOptions {
  double alpha = 0.01;     // family-wise false-alarm probability over the candidates
  int iterations = 6;      // Gauss-Newton iterations
  double min_sigma_px = 0.05;  // floor of the centroid sigma used as weight
  void Check() const;
};

struct FrameCandidate {
  std::string cause;
  double statistic = 0, p_value = 1, delta_bic = 0;
  int dof = 0;
  bool significant = false;
};

struct FrameDiscovery {
  std::string cause = "none";
  std::map<std::string, double> parameters, sigmas;
  Camera fitted_camera;
  double residual_rms_before_arcsec = 0, residual_rms_after_arcsec = 0, gain = 1;  // held-out frames
  double flux_rms_before_mag = 0, flux_rms_after_mag = 0;                         // vignetting only
  std::vector<FrameCandidate> candidates;
  int frames = 0, frames_solved = 0, stars = 0;
  // Measured figures to compare with the simulator (docs/discrepancy.md): flux of a V = 0 star
  // (ADU, geometric mean over the stars), the scatter of flux about it (mag), median spot sigma,
  // background and noise (ADU, medians over frames).
  double zero_point_adu = 0, photometric_scatter_mag = 0, psf_sigma_median_px = 0;
  double background_median_adu = 0, noise_median_adu = 0;
  // Per star, for the quiver plot: position and residual (measured - model, px) before and after.
  std::vector<double> x_px, y_px, dx_before_px, dy_before_px, dx_after_px, dy_after_px;
};

FrameDiscovery DiscoverFrames(const SolvedFrameSet& set, const Camera& camera, const FrameDiscoverOptions& options);

Json FrameDiscoveryToJson(const FrameDiscovery& d);

// DIR/residuals_before.png and DIR/residuals_after.png: residual vectors across the field.
void WriteResidualQuiver(const std::string& dir, const FrameDiscovery& d, const Camera& camera);

}  // namespace ssiu
