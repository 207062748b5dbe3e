// Centroid-list scenes for star identification, in the style of ESA's Kelvins "Star Trackers: First
// Contact" benchmark: catalog stars projected through the camera at an attitude, some missing
// (occulted, below threshold), Gaussian centroid noise, and false objects (planets, satellites,
// hot clusters, city lights) whose brightness follows the real stars' magnitude distribution, so
// that brightness does not tell them apart. Deterministic per seed; the truth is kept per centroid.
//
//   SimulatedScene s = SimulateScene(camera, catalog, RandomAttitude(seed), SceneSimOptions{}, seed);
//   WriteSceneCsv("scene.csv", s);  // read back by `ssiu solve --centroids`
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/catalog.h"
#include "core/types.h"
#include "identify/identify.h"

namespace ssiu {

struct SceneSimOptions {
  double mag_max = 6.0;             // faintest catalog star seen (Kelvins: Hipparcos to about V 6)
  double centroid_noise_px = 0.22;  // 1-sigma per axis (Kelvins: 20 microradian at f = 10973 px)
  double missing_fraction = 0.0;    // each true star is missing with this probability
  // 1-sigma scatter (mag) of every centroid's flux about 10^(-0.4 mag) (photometric noise, colour
  // terms); drawn from its own random stream, so the positions of a seed do not change with it.
  double flux_noise_mag = 0.0;
  int false_objects_min = 0;  // false objects: a whole number drawn uniformly in [min, max]
  int false_objects_max = 0;
  void Check() const;  // throws InputError naming the field
};

struct SimulatedScene {
  Quat q_inertial_from_sensor = Quat::Identity();
  std::vector<Centroid> centroids;  // stars and false objects shuffled; flux = 10^(-0.4 mag) (+ flux_noise_mag)
  std::vector<StarId> star_id;      // per centroid; kInvalidStarId for a false object
  std::vector<double> mag;          // per centroid: the star's V, or the false object's drawn magnitude
  int true_stars = 0, false_objects = 0;
};

SimulatedScene SimulateScene(const Camera& camera, const StarCatalog& catalog, const Quat& q_inertial_from_sensor,
                             const SceneSimOptions& options, uint64_t seed);

// Centroid CSV as `ssiu solve --centroids` reads it (x_px,y_px,flux,sigma_px) plus the truth columns
// star_id (-1 for a false object) and mag, which the solver ignores.
void WriteSceneCsv(const std::string& path, const SimulatedScene& scene);

}  // namespace ssiu
