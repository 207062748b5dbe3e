// Test generator and Monte Carlo for `ssiu discover frames`: a frame set = N frames at random
// attitudes simulated with a "true" camera that differs from the nominal one by one hidden effect
// (lens_distortion k1, focal_length error, principal_point offset, vignetting, hot_pixels,
// psf_shape) or none. Cosmic rays and noise are on in every set, and so are the simulator's 40 hot
// pixels, but with a new defect seed in every frame (transient single-pixel sources, which are not
// the hidden effect) except in a hot_pixels set, where 20-50 hot pixels keep one defect seed over
// the set (persistent, the hidden effect). psf_shape: the true PSF sigma is 1.2 (the model) times
// 1 +- 0.2-0.35, or (seed divisible by 3) a defocus disk of 1.0-1.8 px; the simulator has no ellipticity (FitSpot's
// ellipticity is tested on spots drawn by the test itself, discover_frames_test.cc).
#pragma once

#include <cmath>
#include <iostream>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "attitude/star_solver.h"
#include "core/catalog.h"
#include "core/rng.h"
#include "discover/discover_frames.h"
#include "identify/star_catalog.h"
#include "sim/frame_sim.h"

namespace ssiu::testing {

// Appends a solved frame of attitude q (no spikes, 400 ADU background, 28 ADU noise) to a synthetic
// frame set; its stars are added by the caller with FrameStar::frame = the returned index.
inline int AddSolvedFrame(SolvedFrameSet* set, const Quat& q) {
  const int f = static_cast<int>(set->q.size());
  set->status.push_back(SolveStatus::kSolved);
  set->names.push_back("f" + std::to_string(f));
  set->q.push_back(q);
  set->solved_index.push_back(f);
  set->spikes.emplace_back();
  set->background_adu.push_back(400);
  set->noise_adu.push_back(28);
  return f;
}

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
  std::vector<std::pair<int, int>> truth_hot;  // hot_pixels: the persistent pixels (x, y)
  std::vector<double> truth_hot_adu;           // their excess (ADU)
  SolvedFrameSet set;
};

inline const std::vector<std::string>& FrameCauses() {
  static const std::vector<std::string> k = {"none",       "lens_distortion", "focal_length", "principal_point",
                                             "vignetting", "hot_pixels",      "psf_shape"};
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
  } else if (cause == "pixel_aspect") {  // fy alone, 0.1-0.25 %: 0.5-1.3 px at the top and bottom edges
    c.truth.focal_length_y_px = c.truth.focal_length_px * (1 + sign() * rng.Uniform(1000, 2500) * 1e-6);
    c.truth_params["pixel_aspect"] = c.truth.FocalYPx() / c.truth.focal_length_px;
  } else if (cause == "principal_point") {
    c.truth.cx_px += sign() * rng.Uniform(5, 15);
    c.truth.cy_px += sign() * rng.Uniform(5, 15);
    c.truth_params["cx_px"] = c.truth.cx_px;
    c.truth_params["cy_px"] = c.truth.cy_px;
  } else if (cause == "vignetting") {
    c.sim.vignetting = rng.Uniform(0.2, 0.4);
    c.truth_params["vignetting"] = c.sim.vignetting;
  } else if (cause == "hot_pixels") {
    c.sim.hot_pixels = static_cast<int>(rng.Uniform(20, 51));
    c.sim.defect_seed = static_cast<int>(seed % 100000) + 7;
    c.truth_params["hot_pixel_count"] = c.sim.hot_pixels;
  } else if (cause == "psf_shape") {
    if (seed % 3 == 0) {  // a third of the cases: defocus (a 1.0-1.8 px disk convolved with the model PSF)
      c.sim.defocus_radius_px = rng.Uniform(1.0, 1.8);
    } else {
      c.sim.psf_sigma_px = 1.2 * (1 + sign() * rng.Uniform(0.2, 0.35));
      c.truth_params["psf_sigma_px"] = c.sim.psf_sigma_px;
    }
  }
  std::vector<Image16> imgs;
  std::vector<ImageView> views;
  std::vector<std::string> names;
  for (int f = 0; f < frames; ++f) {
    const uint64_t s = seed * 131 + f;
    FrameSimOptions so = c.sim;
    if (cause != "hot_pixels") so.defect_seed = static_cast<int>(s % 1000000) + 1000;  // transient
    SimulatedFrame sf = SimulateFrame(c.truth, FrameSky(), RandomAttitude(s), so, s);
    if (cause == "hot_pixels" && f == 0) {
      for (const auto& a : sf.artefacts) {
        if (a.type != "hot_pixel") continue;
        c.truth_hot.emplace_back(static_cast<int>(std::lround(a.x_px)), static_cast<int>(std::lround(a.y_px)));
        c.truth_hot_adu.push_back(a.signal_e / so.gain_e_per_adu);
      }
    }
    imgs.push_back(std::move(sf.image));
    names.push_back("frame" + std::to_string(f));
  }
  for (const auto& im : imgs) views.push_back(im.view());
  SolveOptions so;
  so.detect.gain_e_per_adu = c.sim.gain_e_per_adu;
  c.set = SolveFrameSet(FrameIdentifier(), views, names, c.nominal, so);
  return c;
}

// `frames` frames simulated through the true camera at random attitudes (seeds seed0 + f; a new defect
// seed each: transient hot pixels), solved with the nominal camera.
inline SolvedFrameSet SimulateAndSolve(const Camera& truth, const Camera& nominal, FrameSimOptions so, uint64_t seed0,
                                       int frames) {
  std::vector<Image16> imgs;
  std::vector<ImageView> views;
  std::vector<std::string> names;
  for (int f = 0; f < frames; ++f) {
    const uint64_t seed = seed0 + f;
    so.defect_seed = static_cast<int>(seed % 1000000);
    imgs.push_back(SimulateFrame(truth, FrameSky(), RandomAttitude(seed), so, seed).image);
    names.push_back("f" + std::to_string(f));
  }
  for (const auto& im : imgs) views.push_back(im.view());
  SolveOptions solve;
  solve.detect.gain_e_per_adu = so.gain_e_per_adu;
  return SolveFrameSet(FrameIdentifier(), views, names, nominal, solve);
}

struct FrameMcSummary {
  int sets = 0, right = 0, with_effect = 0, geometric_named = 0, geometric_reduced = 0, params = 0, params_3sigma = 0;
  int none_sets = 0, none_right = 0;
  int other_named = 0, other_gain = 0;  // hot_pixels / psf_shape named rightly, and with held-out gain > 1
  int hot_found = 0, hot_detectable = 0, hot_false = 0;  // persistent pixels found / truth above 1000 ADU / not true
};

inline FrameDiscoverOptions McDiscoverOptions() {
  FrameDiscoverOptions o;
  o.psf_sigma_px = 1.2;  // the model PSF (the simulator's default)
  return o;
}

// n sets, the causes in turn (default: all of FrameCauses()).
inline FrameMcSummary RunFrameMonteCarlo(int n, int frames, uint64_t seed0, bool verbose,
                                         const std::vector<std::string>& causes = FrameCauses()) {
  FrameMcSummary s;
  for (int i = 0; i < n; ++i) {
    const std::string cause = causes[i % causes.size()];
    const FrameCase c = MakeFrameCase(cause, seed0 + 17 * i, frames);
    const FrameDiscovery d = DiscoverFrames(c.set, c.nominal, McDiscoverOptions());
    ++s.sets;
    s.right += d.cause == cause;
    s.none_sets += cause == "none";
    s.none_right += cause == "none" && d.cause == "none";
    if (d.cause == cause && (cause == "hot_pixels" || cause == "psf_shape")) {
      ++s.other_named;
      s.other_gain += d.gain > 1;
    }
    if (cause == "hot_pixels") {
      std::set<std::pair<int, int>> truth(c.truth_hot.begin(), c.truth_hot.end());
      for (size_t k = 0; k < c.truth_hot.size(); ++k) {
        if (c.truth_hot_adu[k] < 1000) continue;  // below the solver's detection of a single pixel
        ++s.hot_detectable;
        for (const auto& h : d.hot_pixels) s.hot_found += h.x == c.truth_hot[k].first && h.y == c.truth_hot[k].second;
      }
      for (const auto& h : d.hot_pixels) s.hot_false += !truth.count({h.x, h.y});
    }
    s.with_effect += cause != "none";
    if (d.cause == "lens_distortion" || d.cause == "focal_length" || d.cause == "principal_point" ||
        d.cause == "pixel_aspect") {
      ++s.geometric_named;
      s.geometric_reduced += d.residual_rms_after_arcsec < d.residual_rms_before_arcsec;
    }
    std::string ps;
    if (d.cause == cause) {
      for (const auto& [k, v] : c.truth_params) {
        if (!d.parameters.count(k) || k == "hot_pixel_count") continue;  // hot pixels: checked pixel by pixel
        ++s.params;
        s.params_3sigma += std::abs(d.parameters.at(k) - v) <= 3 * d.sigmas.at(k);
        ps += " " + k + "=" + std::to_string(d.parameters.at(k)) + "(" + std::to_string(v) + "+-" +
              std::to_string(d.sigmas.at(k)) + ")";
      }
    }
    if (verbose) {
      std::cout << "set " << i << " true " << cause << (c.sim.defocus_radius_px > 0 ? " (defocus)" : "") << " found "
                << d.cause << " solved " << d.frames_solved << "/" << d.frames << " stars " << d.stars << " rms "
                << d.residual_rms_before_arcsec << " -> " << d.residual_rms_after_arcsec << " gain " << d.gain << ps
                << " | zero point " << d.zero_point_adu << " ADU, scatter " << d.photometric_scatter_mag
                << " mag, spot sigma " << d.psf_sigma_median_px << " px (stamp fit " << d.psf_sigma_fit_px << ", e "
                << d.psf_e1 << ", " << d.psf_e2 << ", " << d.psf_stars << " stars), background "
                << d.background_median_adu << " noise " << d.noise_median_adu << " ADU, persistent pixels "
                << d.hot_pixels.size() << "\n";
      for (const auto& cd : d.candidates)
        std::cout << "   " << cd.cause << " stat " << cd.statistic << " p " << cd.p_value << " dbic " << cd.delta_bic
                  << (cd.evaluated
                          ? " gain " + std::to_string(cd.gain) + " z " + std::to_string(cd.gain_z) + " " + cd.verdict
                          : "")
                  << "\n";
      std::cout << "   residual p " << d.residual.p_value << " (" << d.residual.finding << "):";
      for (const auto& t : d.residual.tests)
        std::cout << " " << t.name << " F " << t.f << " (" << t.dof << ", " << t.dof_resid << ") p " << t.p_value
                  << ";";
      std::cout << "\n";
    }
  }
  return s;
}

}  // namespace ssiu::testing
