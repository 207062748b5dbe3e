// Test helper: synthetic centroids from catalog stars projected at a known attitude, with noise,
// dropped stars and false stars (an independent truth for identification tests).
#pragma once

#include <cmath>
#include <memory>
#include <vector>

#include "core/camera.h"
#include "core/catalog.h"
#include "core/rng.h"
#include "identify/identify.h"
#include "identify/star_catalog.h"

namespace ssiu::testing {

struct SyntheticFrame {
  std::vector<Centroid> centroids;
  std::vector<StarId> truth_id;  // per centroid; kInvalidStarId for a false star
};

struct SyntheticOptions {
  double sigma_px = 0.2;
  double drop_fraction = 0.1;
  int false_stars = 3;
  double mag_max = 99;
};

// One BSC solver catalog for a 16.6 deg field, built once per test program.
inline const StarIdentifier& Bsc166() {
  static const std::unique_ptr<StarIdentifier> id = [] {
    CatalogBuildOptions o;
    o.fov_deg = 16.6;
    return std::make_unique<StarIdentifier>(BuildSolverCatalog(LoadSourceCatalog(DefaultBscPath()), o));
  }();
  return *id;
}

inline SyntheticFrame MakeSyntheticFrame(const SolverCatalog& cat, const Camera& cam, const Quat& q,
                                         const SyntheticOptions& o, Rng* rng) {
  SyntheticFrame f;
  const Mat3 rt = q.toRotationMatrix().transpose();
  const Vec3 bore = q.toRotationMatrix().col(2);
  const double cos_lim = std::cos(cam.FovDiagRad() / 2 * 1.1);
  for (const auto& s : cat.stars) {
    if (s.mag > o.mag_max || s.unit.dot(bore) < cos_lim) continue;
    const auto p = cam.Project(rt * s.unit);
    if (!p || !cam.InImage(*p)) continue;
    if (rng->Uniform() < o.drop_fraction) continue;
    Centroid c;
    c.x_px = (*p)[0] + o.sigma_px * rng->Normal();
    c.y_px = (*p)[1] + o.sigma_px * rng->Normal();
    c.flux = std::pow(10.0, -0.4 * s.mag);
    c.sigma_px = o.sigma_px;
    f.centroids.push_back(c);
    f.truth_id.push_back(s.id);
  }
  for (int i = 0; i < o.false_stars; ++i) {
    Centroid c;
    c.x_px = rng->Uniform(0, cam.width - 1);
    c.y_px = rng->Uniform(0, cam.height - 1);
    // False stars as bright as mid-field stars (planets, satellites): they enter the patterns.
    c.flux = std::pow(10.0, -0.4 * rng->Uniform(2.0, 5.0));
    c.sigma_px = o.sigma_px;
    f.centroids.push_back(c);
    f.truth_id.push_back(kInvalidStarId);
  }
  return f;
}

}  // namespace ssiu::testing
