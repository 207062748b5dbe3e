// Test helper: the acceptance campaign of issue 4 on simulated frames (SimulateFrame + Detect +
// SolveCentroids): random attitudes over the whole sky, FOV 8-20 deg, default simulator noise,
// 3 false stars per frame and 10% of the detected true stars removed.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/catalog.h"
#include "core/rng.h"
#include "sim/frame_sim.h"

namespace ssiu::testing {

struct CampaignStats {
  int frames = 0, solved = 0, wrong = 0;  // wrong: solved more than 1 arcmin from truth
  std::vector<double> cross_arcsec_166;   // boresight errors of the 16.6 deg frames
  double nees_sum = 0;
  std::vector<double> nees;
  int nees_n = 0;
  std::vector<double> solve_ms;
  std::map<int, int> unsolved_by_fov_deg;
};

inline CampaignStats RunCampaign(int n_frames, uint64_t seed0) {
  // The sky: Hipparcos/Tycho (KStars) to V 7 when installed, so that the 8-deg fields hold enough
  // stars (the BSC alone leaves some 8-deg fields with fewer than 5 stars); else the BSC.
  static const StarCatalog sky = [] {
    const std::string kstars = "/usr/share/kstars/stars.dat";
    if (!std::ifstream(kstars)) return LoadXplanetBsc(DefaultBscPath(), 7.0);
    StarCatalog c;
    c.source = kstars;
    for (const auto& s : LoadKstarsStars(kstars).stars)
      if (s.star.mag <= 7.0) c.stars.push_back(s.star);
    return c;
  }();
  static std::map<int, std::unique_ptr<StarIdentifier>> ids;  // by FOV in tenths of a degree
  const double fovs[] = {8.0, 12.0, 16.6, 20.0};
  CampaignStats st;
  for (int i = 0; i < n_frames; ++i) {
    const uint64_t seed = seed0 + static_cast<uint64_t>(i);
    Rng rng(seed * 7919 + 1);
    const double fov = fovs[i % 4];
    const int key = static_cast<int>(std::lround(fov * 10));
    if (!ids.count(key)) {
      CatalogBuildOptions co;
      co.fov_deg = fov;
      ids[key] = std::make_unique<StarIdentifier>(BuildSolverCatalog(sky, co));
    }
    const Camera cam = MakeCamera(1024, 1024, fov);
    FrameSimOptions fo;
    fo.false_stars = 3;
    const Quat q = RandomAttitude(seed);
    const SimulatedFrame sf = SimulateFrame(cam, sky, q, fo, seed);
    DetectOptions dopt = SolveOptions{}.detect;
    dopt.gain_e_per_adu = fo.gain_e_per_adu;
    const Detections det = Detect(sf.image.view(), dopt);
    // Remove 10% of the detections that are true stars (a detection within 2 px of a drawn star).
    std::vector<Centroid> cs;
    for (const auto& c : CentroidsFromDetections(det, SolveOptions{}.detector_sigma_scale)) {
      bool is_star = false;
      for (const auto& s : sf.stars)
        if (s.star_id != kInvalidStarId && std::hypot(s.x_px - c.x_px, s.y_px - c.y_px) < 2) is_star = true;
      if (is_star && rng.Uniform() < 0.1) continue;
      cs.push_back(c);
    }
    SolveOptions so;
    so.identify.systematic_px = 0;  // simulated optics: no unmodelled error, the fit's sigma is all
    const SolveResult r = SolveCentroids(*ids[key], cs, cam, so);
    ++st.frames;
    st.solve_ms.push_back(r.timing_ms.count("identify") ? r.timing_ms.at("identify") : 0.0);
    if (r.status != SolveStatus::kSolved) {
      ++st.unsolved_by_fov_deg[static_cast<int>(fov)];
      continue;
    }
    ++st.solved;
    const Quat qe = r.attitude.q_inertial_from_sensor;
    if (const double err_arcsec = AttitudeErrorRad(qe, q) * kRadToArcsec; err_arcsec > 60) {
      ++st.wrong;
      std::printf(
          "wrong: seed %llu, %.1f deg, %.0f arcsec off, %zu matches, focal length refined %d, principal point refined "
          "%d (%.1f, %.1f px; p %.2g)\n",
          static_cast<unsigned long long>(seed), fov, err_arcsec, r.identification.matches.size(),
          static_cast<int>(r.identification.focal_length_refined),
          static_cast<int>(r.identification.principal_point_refined), r.identification.cx_px, r.identification.cy_px,
          r.identification.principal_point_p_value);
    }
    if (fov == 16.6) st.cross_arcsec_166.push_back(SplitAttitudeError(qe, q).cross_rad * kRadToArcsec);
    Quat d = q.conjugate() * qe;
    if (d.w() < 0) d.coeffs() = -d.coeffs();
    const Vec3 e = 2 * d.vec();
    st.nees.push_back(e.dot(r.attitude.covariance_rad2.inverse() * e));
    st.nees_sum += st.nees.back();
    ++st.nees_n;
  }
  return st;
}

inline double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace ssiu::testing
