// Internal to discover_frames: the psf_shape and hot_pixels candidates (discover_frames_psf.cc),
// combined with the geometric and photometric ones in DiscoverFrames.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "analysis/discover_frames.h"

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

}  // namespace ssiu::discover_internal
