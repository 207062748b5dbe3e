// Internal to discover_frames: the psf_shape and hot_pixels candidates (discover_frames_psf.cc),
// combined with the geometric and photometric ones in DiscoverFrames.
#pragma once

#include <Eigen/Dense>
#include <map>
#include <string>
#include <vector>

#include "discover/discover_frames.h"

namespace ssiu::discover_internal {

struct CauseResult {
  FrameCandidate candidate;
  bool tested = false;
  std::map<std::string, double> parameters, sigmas;
  double before = 0, after = 0, gain = 1;  // held-out figure before and after the fix
};

// psf_shape against the model sigma o.psf_sigma_px. Also fills d->psf_sigma_fit_px, psf_e1/e2,
// psf_stars (measured whether or not the model sigma is known).
CauseResult AnalysePsfShape(const SolvedFrameSet& set, const Camera& camera, const FrameDiscoverOptions& o,
                            FrameDiscovery* d);

// hot_pixels: persistent single-pixel spikes. Fills d->hot_pixels / hot_pixel_frames.
CauseResult AnalyseHotPixels(const SolvedFrameSet& set, const FrameDiscoverOptions& o, FrameDiscovery* d);

// The vignetting law y = c + ln(1 - v u) fitted to y = ln(flux) + 0.4 ln(10) V against u = (r / r_corner)^2
// by a 1-D search over v in [-1, 0.95] (c is the mean for each v). Returns v; *sigma (if non-null): its
// sigma from the curvature of the sum of squares with the residual scale.
double FitVignettingLaw(const std::vector<double>& u, const std::vector<double>& y, double* sigma);

// `unexplained`: the star position residuals res_w (2 per star of set.stars, measured - model divided
// by max(sigma, min_sigma_px)) of the fullest model of the vocabulary, whose whitened Jacobian is jac,
// and the stars' photometric residuals about the fitted vignetting law, tested for structure.
FrameResidual TestFrameResidual(const SolvedFrameSet& set, const Camera& camera, const Eigen::MatrixXd& jac,
                                const Eigen::VectorXd& res_w, const FrameDiscoverOptions& o);

}  // namespace ssiu::discover_internal
