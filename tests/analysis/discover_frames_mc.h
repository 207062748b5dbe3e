// Test generator and Monte Carlo for `ssiu discover frames`: a frame set = N frames at random
// attitudes simulated with a "true" camera that differs from the nominal one by one hidden effect
// (lens_distortion k1, focal_length error, principal_point offset, vignetting) or none. The
// simulator's usual hot pixels (fixed defect seed), cosmic rays and noise are on.
#pragma once

#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "analysis/discover_frames.h"
#include "attitude/star_solver.h"
#include "core/catalog.h"
#include "core/rng.h"
#include "identify/star_catalog.h"
#include "sim/frame_sim.h"

namespace ssiu::testing {

inline const StarCatalog& FrameSky() {
  static const StarCatalog sky = LoadXplanetBsc(DefaultBscPath(), 7.0);
  return sky;
}
inline const StarIdentifier& FrameIdentifier() {
  static const std::unique_ptr<StarIdentifier> id = [] {
    CatalogBuildOptions co;
    co.fov_deg = 16.6;
    return std::make_unique<StarIdentifier>(BuildSolverCatalog(FrameSky(), co));
  }();
  return *id;
}

struct FrameCase {
  std::string cause;
  Camera nominal, truth;
  FrameSimOptions sim;
  std::map<std::string, double> truth_params;
  SolvedFrameSet set;
};

inline const std::vector<std::string>& FrameCauses() {
  static const std::vector<std::string> k = {"none", "lens_distortion", "focal_length", "principal_point", "vignetting"};
  return k;
}

inline FrameCase MakeFrameCase(const std::string& cause, uint64_t seed, int frames) {
  Rng rng(seed);
  FrameCase c;
  c.cause = cause;
  c.nominal = MakeCamera(1024, 1024, 16.6);
  c.truth = c.nominal;
  auto sign = [&] { return rng.Uniform() < 0.5 ? -1.0 : 1.0; };
  if (cause == "lens_distortion") {
    c.truth.distortion.k1 = sign() * rng.Uniform(0.02, 0.06);  // 0.5-1.5 px at the corners
    c.truth_params["k1"] = c.truth.distortion.k1;
  } else if (cause == "focal_length") {
    c.truth.focal_length_px *= 1 + sign() * rng.Uniform(500, 1500) * 1e-6;
    c.truth_params["focal_length_px"] = c.truth.focal_length_px;
  } else if (cause == "principal_point") {
    c.truth.cx_px += sign() * rng.Uniform(5, 15);
    c.truth.cy_px += sign() * rng.Uniform(5, 15);
    c.truth_params["cx_px"] = c.truth.cx_px;
    c.truth_params["cy_px"] = c.truth.cy_px;
  } else if (cause == "vignetting") {
    c.sim.vignetting = rng.Uniform(0.2, 0.4);
    c.truth_params["vignetting"] = c.sim.vignetting;
  }
  std::vector<Image16> imgs;
  std::vector<ImageView> views;
  std::vector<std::string> names;
  for (int f = 0; f < frames; ++f) {
    const uint64_t s = seed * 131 + f;
    imgs.push_back(SimulateFrame(c.truth, FrameSky(), RandomAttitude(s), c.sim, s).image);
    names.push_back("frame" + std::to_string(f));
  }
  for (const auto& im : imgs) views.push_back(im.view());
  SolveOptions so;
  so.detect.gain_e_per_adu = c.sim.gain_e_per_adu;
  c.set = SolveFrameSet(FrameIdentifier(), views, names, c.nominal, so);
  return c;
}

struct FrameMcSummary {
  int sets = 0, right = 0, with_effect = 0, geometric_named = 0, geometric_reduced = 0, params = 0, params_3sigma = 0;
};

inline FrameMcSummary RunFrameMonteCarlo(int n, int frames, uint64_t seed0, bool verbose) {
  FrameMcSummary s;
  for (int i = 0; i < n; ++i) {
    const std::string cause = FrameCauses()[i % FrameCauses().size()];
    const FrameCase c = MakeFrameCase(cause, seed0 + 17 * i, frames);
    const FrameDiscovery d = DiscoverFrames(c.set, c.nominal, FrameDiscoverOptions{});
    ++s.sets;
    s.right += d.cause == cause;
    s.with_effect += cause != "none";
    if (d.cause != "none" && d.cause != "vignetting") {
      ++s.geometric_named;
      s.geometric_reduced += d.residual_rms_after_arcsec < d.residual_rms_before_arcsec;
    }
    std::string ps;
    if (d.cause == cause) {
      for (const auto& [k, v] : c.truth_params) {
        if (!d.parameters.count(k)) continue;
        ++s.params;
        s.params_3sigma += std::abs(d.parameters.at(k) - v) <= 3 * d.sigmas.at(k);
        ps += " " + k + "=" + std::to_string(d.parameters.at(k)) + "(" + std::to_string(v) + "+-" +
              std::to_string(d.sigmas.at(k)) + ")";
      }
    }
    if (verbose) {
      std::cout << "set " << i << " true " << cause << " found " << d.cause << " solved " << d.frames_solved << "/"
                << d.frames << " stars " << d.stars << " rms " << d.residual_rms_before_arcsec << " -> "
                << d.residual_rms_after_arcsec << " gain " << d.gain << ps << " | zero point " << d.zero_point_adu
                << " ADU, scatter " << d.photometric_scatter_mag << " mag, spot sigma " << d.psf_sigma_median_px
                << " px, background " << d.background_median_adu << " noise " << d.noise_median_adu << " ADU\n";
      for (const auto& cd : d.candidates)
        std::cout << "   " << cd.cause << " stat " << cd.statistic << " p " << cd.p_value << " dbic " << cd.delta_bic << "\n";
    }
  }
  return s;
}

}  // namespace ssiu::testing
