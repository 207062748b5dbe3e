#include "sim/scene_sim.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/csv.h"
#include "core/error.h"
#include "core/rng.h"

namespace ssiu {

void SceneSimOptions::Check() const {
  auto bad = [](const std::string& f, const std::string& w) { throw InputError("scene options", f + " " + w); };
  if (!(mag_max > -2 && mag_max < 20)) bad("mag_max", "must be in (-2, 20)");
  if (!(centroid_noise_px >= 0 && centroid_noise_px < 50)) bad("centroid_noise_px", "must be in [0, 50)");
  if (!(missing_fraction >= 0 && missing_fraction <= 1)) bad("missing_fraction", "must be in [0, 1]");
  if (!(flux_noise_mag >= 0 && flux_noise_mag <= 5)) bad("flux_noise_mag", "must be in [0, 5]");
  if (false_objects_min < 0 || false_objects_min > 10000) bad("false_objects_min", "must be in [0, 10000]");
  if (false_objects_max < false_objects_min || false_objects_max > 10000)
    bad("false_objects_max", "must be in [false_objects_min, 10000]");
}

SimulatedScene SimulateScene(const Camera& camera, const StarCatalog& catalog, const Quat& q_inertial_from_sensor,
                             const SceneSimOptions& o, uint64_t seed) {
  o.Check();
  camera.Check();
  Rng rng(seed);
  Rng rng_flux(seed ^ 0x9e3779b97f4a7c15ULL);  // photometric noise: its own stream
  SimulatedScene s;
  s.q_inertial_from_sensor = q_inertial_from_sensor.normalized();
  const Mat3 r = s.q_inertial_from_sensor.toRotationMatrix();
  const Mat3 rt = r.transpose();
  const double cos_lim = std::cos(std::min(camera.FovDiagRad() / 2 * 1.05 + 0.01, kPi));
  std::vector<double> mags;  // every catalog magnitude seen, for the false objects' distribution
  auto add = [&](double x, double y, double mag, StarId id) {
    Centroid c;
    c.x_px = x + o.centroid_noise_px * rng.Normal();
    c.y_px = y + o.centroid_noise_px * rng.Normal();
    c.flux = std::pow(10.0, -0.4 * (mag + (o.flux_noise_mag > 0 ? o.flux_noise_mag * rng_flux.Normal() : 0.0)));
    c.sigma_px = o.centroid_noise_px;
    s.centroids.push_back(c);
    s.star_id.push_back(id);
    s.mag.push_back(mag);
  };
  for (const auto& star : catalog.stars) {
    if (star.mag > o.mag_max) continue;
    mags.push_back(star.mag);
    if (star.unit.dot(r.col(2)) < cos_lim) continue;
    const auto p = camera.Project(rt * star.unit);
    if (!p || !camera.InImage(*p)) continue;
    if (rng.Uniform() < o.missing_fraction) continue;
    add((*p)[0], (*p)[1], star.mag, star.id);
    ++s.true_stars;
  }
  if (o.false_objects_max > 0 && mags.empty()) throw InputError(catalog.source, "no star brighter than mag_max");
  const int span = o.false_objects_max - o.false_objects_min + 1;
  s.false_objects = o.false_objects_min + std::min(span - 1, static_cast<int>(rng.Uniform() * span));
  for (int i = 0; i < s.false_objects; ++i) {
    // A magnitude drawn from the catalog's stars (all sky, to mag_max): the false objects are as
    // bright as the stars are, in distribution.
    const size_t k = std::min(mags.size() - 1, static_cast<size_t>(rng.Uniform() * mags.size()));
    // y before x, one statement each: the order of a call's arguments is unspecified (GCC and clang
    // differ), and the same seed must give the same scene whatever compiled it.
    const double y = rng.Uniform(-0.5, camera.height - 0.5);
    const double x = rng.Uniform(-0.5, camera.width - 0.5);
    add(x, y, mags[k], kInvalidStarId);
  }
  // Shuffle (Fisher-Yates with our Rng): the list order tells nothing.
  std::vector<size_t> perm(s.centroids.size());
  std::iota(perm.begin(), perm.end(), 0);
  for (size_t i = perm.size(); i > 1; --i) std::swap(perm[i - 1], perm[static_cast<size_t>(rng.Uniform() * i) % i]);
  SimulatedScene out = s;
  for (size_t i = 0; i < perm.size(); ++i) {
    out.centroids[i] = s.centroids[perm[i]];
    out.star_id[i] = s.star_id[perm[i]];
    out.mag[i] = s.mag[perm[i]];
  }
  return out;
}

void WriteSceneCsv(const std::string& path, const SimulatedScene& scene) {
  std::vector<std::vector<double>> cols(6);
  for (size_t i = 0; i < scene.centroids.size(); ++i) {
    const Centroid& c = scene.centroids[i];
    cols[0].push_back(c.x_px);
    cols[1].push_back(c.y_px);
    cols[2].push_back(c.flux);
    cols[3].push_back(c.sigma_px);
    cols[4].push_back(scene.star_id[i]);
    cols[5].push_back(scene.mag[i]);
  }
  WriteCsv(path, {"x_px", "y_px", "flux", "sigma_px", "star_id", "mag"}, cols);
}

}  // namespace ssiu
