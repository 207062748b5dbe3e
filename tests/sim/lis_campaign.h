// Lost-in-space campaigns on simulated scenes (sim/scene_sim.h), shared by the normal and the long
// tests: Kelvins-style scenes among false objects, and chance-probability calibration runs in which
// every solve is a false match.
#pragma once

#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/catalog.h"
#include "core/rng.h"
#include "identify/identify.h"
#include "identify/star_catalog.h"
#include "sim/frame_sim.h"
#include "sim/scene_sim.h"
#include "testing/testing.h"

namespace ssiu::testing {

// ESA Kelvins "Star Trackers: First Contact" geometry: 10 x 7.5 deg, 1920 x 1440 px, 20 microradian
// centroid noise, stars to V 6.
inline Camera KelvinsCamera() { return MakeCamera(1920, 1440, 10.0); }
inline double KelvinsNoisePx() { return 20e-6 * KelvinsCamera().focal_length_px; }

// The BSC solver catalog for a field of fov_deg (stars to V 6.5 at 10 deg), built once per FOV.
inline const StarIdentifier& BscIdentifier(double fov_deg) {
  static std::map<double, std::unique_ptr<StarIdentifier>> ids;
  auto& id = ids[fov_deg];
  if (!id) {
    CatalogBuildOptions o;
    o.fov_deg = fov_deg;
    id = std::make_unique<StarIdentifier>(BuildSolverCatalog(LoadSourceCatalog(DefaultBscPath()), o));
  }
  return *id;
}

// Wrong, as in bench/identify_bench.cc: the boresight more than 1 arcmin off, or the roll off by more
// than 1 arcmin and 5 of its reported sigmas (a 10-deg field with 4-arcsec centroids and five stars
// has a roll sigma of ~20 arcsec).
inline bool IsWrong(const SolveResult& r, const Quat& truth) {
  const AttitudeErrorSplit e = SplitAttitudeError(r.attitude.q_inertial_from_sensor, truth);
  const double roll_limit = std::max(60.0, 5 * r.attitude.sigma_roll_rad * kRadToArcsec);
  return e.cross_rad * kRadToArcsec > 60 || std::abs(e.roll_rad) * kRadToArcsec > roll_limit;
}

// Matches whose catalog star is the scene's truth for that centroid.
inline int RightMatches(const SimulatedScene& s, const ScratchVec<StarMatch>& matches) {
  int n = 0;
  for (const auto& m : matches) n += s.star_id[m.centroid] == m.star_id;
  return n;
}

struct SceneCampaign {
  int scenes = 0;
  int with4 = 0, solved4 = 0;                   // scenes with >= 4 true stars and of them solved
  int with3 = 0, solved3 = 0;                   // exactly 3 true stars
  int wrong = 0;                                // solved more than 1 arcmin off
  std::vector<double> ms;                       // identify wall time per scene
  std::vector<double> solved_ms;                // the same, solved scenes
  std::map<int, std::pair<int, int>> by_stars;  // true stars -> (scenes, solved)
};

inline IdentifyOptions KelvinsIdentifyOptions() {
  IdentifyOptions io;
  io.systematic_px = 0.0;  // the scenes' centroids carry their (exact) noise sigma
  io.timeout_ms = 0.0;     // deterministic: the hypothesis budget, not the clock
  return io;
}

inline SceneCampaign RunKelvinsScenes(int n, uint64_t seed0, const IdentifyOptions& io, double flux_noise_mag = 0.0) {
  const Camera cam = KelvinsCamera();
  const StarIdentifier& id = BscIdentifier(10.0);
  SceneSimOptions so;
  so.centroid_noise_px = KelvinsNoisePx();
  so.false_objects_min = 0;
  so.false_objects_max = 80;
  so.flux_noise_mag = flux_noise_mag;
  SceneCampaign c;
  for (int k = 0; k < n; ++k) {
    const uint64_t seed = seed0 + k;
    const SimulatedScene s = SimulateScene(cam, Bsc(), RandomAttitude(seed), so, seed);
    SolveOptions so;
    so.identify = io;
    const SolveResult sr = SolveCentroids(id, s.centroids, cam, so);
    const Identification& r = sr.identification;
    c.ms.push_back(r.timing_ms.count("identify") ? r.timing_ms.at("identify") : 0.0);
    ++c.scenes;
    const bool ok = r.status == SolveStatus::kSolved;
    if (ok) c.solved_ms.push_back(c.ms.back());
    if (ok && IsWrong(sr, s.q_inertial_from_sensor)) {
      const double err_arcsec =
          AttitudeErrorRad(sr.attitude.q_inertial_from_sensor, s.q_inertial_from_sensor) * kRadToArcsec;
      ++c.wrong;
      const int true_matches = RightMatches(s, r.matches);
      std::fprintf(stderr, "WRONG scene seed %llu: %.1f arcsec off, %zu matches (%d right), chance %.3g, %s\n",
                   static_cast<unsigned long long>(seed), err_arcsec, r.matches.size(), true_matches,
                   r.false_match_probability, r.message.c_str());
    }
    if (s.true_stars >= 4) c.with4 += 1, c.solved4 += ok;
    c.by_stars[s.true_stars].first += 1;
    c.by_stars[s.true_stars].second += ok;
    if (s.true_stars == 3) c.with3 += 1, c.solved3 += ok;
  }
  return c;
}

// Calibration runs: the false solves counted are accepted solves that are wrong.
struct Calibration {
  int trials = 0, false_solves = 0, solved = 0;
};

// A uniformly random centroid set for seed: min_centroids to max_centroids centroids anywhere on a
// 1024 x 1024 px image, uniform random fluxes, sigma 0.3 px.
// How a random set's fluxes are drawn: uniform in (0, 1) (few faint ones), or as stars are, 10^(-0.4 m)
// with m in [0, 7] following the star counts N(< m) ~ 10^(0.5 m) (most near the faint end), or with m
// uniform in [0, 7]. The photometric tests must be calibrated under each.
enum class RandomFlux { kUniform, kStarCounts, kFlatMagnitude };

inline std::vector<Centroid> RandomCentroidSet(uint64_t seed, int min_centroids, int max_centroids,
                                               RandomFlux flux = RandomFlux::kUniform) {
  Rng rng(seed);
  const int m = min_centroids + static_cast<int>(rng.Uniform() * (max_centroids - min_centroids + 1));
  std::vector<Centroid> cs(m);
  for (auto& x : cs) {
    x = {rng.Uniform(0, 1023), rng.Uniform(0, 1023), rng.Uniform(), 0.3};
    if (flux == RandomFlux::kStarCounts) {
      const double mag = std::log10(x.flux * (std::pow(10.0, 0.5 * 7) - 1) + 1) / 0.5;  // inverse of the CDF
      x.flux = std::pow(10.0, -0.4 * mag);
    } else if (flux == RandomFlux::kFlatMagnitude) {
      x.flux = std::pow(10.0, -0.4 * 7 * x.flux);
    }
  }
  return cs;
}
inline Camera RandomSetCamera() { return MakeCamera(1024, 1024, 16.6); }

// Uniformly random centroid sets (8 to max_centroids) on a 1024-px 16.6-deg camera: every solve is false.
inline Calibration RunRandomCentroids(int n, uint64_t seed0, const IdentifyOptions& io, int max_centroids = 40) {
  const StarIdentifier& id = BscIdentifier(16.6);
  Calibration c;
  for (int k = 0; k < n; ++k) {
    const std::vector<Centroid> cs = RandomCentroidSet(seed0 + k, 8, max_centroids);
    ++c.trials;
    const Identification r = id.Identify(cs, RandomSetCamera(), io);
    const bool ok = r.status == SolveStatus::kSolved;
    if (ok)
      std::fprintf(stderr, "FALSE random set seed %llu: %zu centroids, %s, chance %.3g, %d hypotheses\n",
                   static_cast<unsigned long long>(seed0 + k), cs.size(), r.message.c_str(), r.false_match_probability,
                   r.hypotheses);
    c.false_solves += ok;
    c.solved += ok;
  }
  return c;
}

// The smallest chance probability of each random set's whole search (nothing accepted: the threshold is
// 1e-300, so the search runs to its end and reports the best). The search is the same at every threshold
// up to its first acceptance, so a set would be solved at alpha only if this is below alpha: the share
// of sets below alpha bounds the false-solve rate at every threshold at once.
inline std::vector<double> RandomSetsBestChance(int n, uint64_t seed0, IdentifyOptions io, int min_centroids,
                                                int max_centroids, RandomFlux flux = RandomFlux::kUniform) {
  const StarIdentifier& id = BscIdentifier(16.6);
  io.max_false_match_prob = 1e-300;
  std::vector<double> best;
  for (int k = 0; k < n; ++k) {
    const Identification r =
        id.Identify(RandomCentroidSet(seed0 + k, min_centroids, max_centroids, flux), RandomSetCamera(), io);
    if (r.status == SolveStatus::kSolved)
      std::fprintf(stderr, "random set seed %llu solved at 1e-300\n", static_cast<unsigned long long>(seed0 + k));
    best.push_back(r.status == SolveStatus::kSolved ? 0.0 : r.false_match_probability);
  }
  return best;
}

// Real stars (a Kelvins scene at the true focal length) solved with a camera whose focal length is
// wrong by 5-15 % in tolerance mode with the given tolerance: a solve more than 1 arcmin off is false.
inline Calibration RunWrongFocal(int n, uint64_t seed0, double tol_pct, IdentifyOptions io) {
  const Camera truth = KelvinsCamera();
  const StarIdentifier& id = BscIdentifier(10.0);
  io.fov_tolerance_pct = tol_pct;
  SceneSimOptions so;
  so.centroid_noise_px = KelvinsNoisePx();
  so.false_objects_max = 40;
  Calibration c;
  for (int k = 0; k < n; ++k) {
    const uint64_t seed = seed0 + k;
    Rng rng(seed);
    Camera guess = truth;
    guess.focal_length_px *= (rng.Uniform() < 0.5 ? 1 - rng.Uniform(0.05, 0.15) : 1 + rng.Uniform(0.05, 0.15));
    const SimulatedScene s = SimulateScene(truth, Bsc(), RandomAttitude(seed), so, seed);
    SolveOptions sopt;
    sopt.identify = io;
    const SolveResult r = SolveCentroids(id, s.centroids, guess, sopt);
    ++c.trials;
    c.solved += r.status == SolveStatus::kSolved;
    if (r.status == SolveStatus::kSolved && IsWrong(r, s.q_inertial_from_sensor)) {
      ++c.false_solves;
      const AttitudeErrorSplit e = SplitAttitudeError(r.attitude.q_inertial_from_sensor, s.q_inertial_from_sensor);
      const int true_matches = RightMatches(s, r.identification.matches);
      std::fprintf(stderr,
                   "WRONG focal seed %llu: cross %.1f roll %.1f arcsec (sigma %.1f), %zu matches (%d right), "
                   "f %.1f (true %.1f, guess %.1f), chance %.3g, %s\n",
                   static_cast<unsigned long long>(seed), e.cross_rad * kRadToArcsec, e.roll_rad * kRadToArcsec,
                   r.attitude.sigma_roll_rad * kRadToArcsec, r.identification.matches.size(), true_matches,
                   r.identification.focal_length_px, truth.focal_length_px, guess.focal_length_px,
                   r.identification.false_match_probability, r.message.c_str());
    }
  }
  return c;
}

}  // namespace ssiu::testing
