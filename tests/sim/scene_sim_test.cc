#include "sim/scene_sim.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/camera.h"
#include "core/error.h"
#include "sim/frame_sim.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using testing::Bsc;

// Kelvins-style camera: 10 x 7.5 deg, 1920 x 1440 px.
Camera Kelvins() { return MakeCamera(1920, 1440, 10.0); }

TEST(SceneSim, TrueStarsAreCatalogStarsThroughTheCamera) {
  const Camera cam = Kelvins();
  SceneSimOptions o;
  o.centroid_noise_px = 0.3;
  std::map<StarId, Vec3> unit;
  for (const auto& s : Bsc().stars) unit[s.id] = s.unit;
  int stars = 0;
  double sum_sq = 0;
  for (int k = 0; k < 40; ++k) {
    const Quat q = RandomAttitude(100 + k);
    const SimulatedScene s = SimulateScene(cam, Bsc(), q, o, 100 + k);
    ASSERT_EQ(s.centroids.size(), s.star_id.size());
    EXPECT_EQ(s.false_objects, 0);
    EXPECT_EQ(static_cast<int>(s.centroids.size()), s.true_stars);
    // Every star of V <= 6 in the field is there (an independent projection with the camera).
    int expected = 0;
    for (const auto& st : Bsc().stars) {
      const Vec3 b = q.conjugate() * st.unit;
      if (st.mag > o.mag_max || b.z() <= 0) continue;
      const Vec2 p(cam.cx_px + cam.focal_length_px * b.x() / b.z(), cam.cy_px + cam.focal_length_px * b.y() / b.z());
      if (!cam.InImage(p)) continue;
      ++expected;
      const auto it = std::find(s.star_id.begin(), s.star_id.end(), st.id);
      ASSERT_NE(it, s.star_id.end()) << "star " << st.id << " missing";
      const Centroid& c = s.centroids[it - s.star_id.begin()];
      sum_sq += (Vec2(c.x_px, c.y_px) - p).squaredNorm();
      ++stars;
      EXPECT_NEAR(c.flux, std::pow(10.0, -0.4 * st.mag), 1e-12);
    }
    EXPECT_EQ(s.true_stars, expected);
  }
  ASSERT_GT(stars, 150);
  // Per-axis noise from 2 * stars residuals: within 15 % of the 0.3 px asked for.
  EXPECT_NEAR(std::sqrt(sum_sq / (2 * stars)), 0.3, 0.045);
}

TEST(SceneSim, FalseObjectsAndMissingStars) {
  const Camera cam = Kelvins();
  SceneSimOptions o;
  o.false_objects_min = 0;
  o.false_objects_max = 80;
  o.missing_fraction = 0.25;
  std::vector<double> false_mag, star_mag;
  int n_false_min = 1000, n_false_max = -1, seen = 0, missing_ref = 0;
  for (int k = 0; k < 300; ++k) {
    const Quat q = RandomAttitude(7 + k);
    const SimulatedScene s = SimulateScene(cam, Bsc(), q, o, 7 + k);
    SceneSimOptions all = o;
    all.missing_fraction = 0;
    all.false_objects_max = 0;
    missing_ref += SimulateScene(cam, Bsc(), q, all, 7 + k).true_stars;
    seen += s.true_stars;
    n_false_min = std::min(n_false_min, s.false_objects);
    n_false_max = std::max(n_false_max, s.false_objects);
    int nf = 0;
    for (size_t i = 0; i < s.centroids.size(); ++i) {
      const auto& c = s.centroids[i];
      EXPECT_TRUE(cam.InImage(Vec2(c.x_px, c.y_px), -1.0));
      if (s.star_id[i] == kInvalidStarId) {
        ++nf;
        false_mag.push_back(s.mag[i]);
      }
    }
    EXPECT_EQ(nf, s.false_objects);
    EXPECT_EQ(static_cast<int>(s.centroids.size()), s.true_stars + s.false_objects);
  }
  EXPECT_LE(n_false_min, 3);
  EXPECT_GE(n_false_max, 77);
  EXPECT_LE(n_false_max, 80);
  // A quarter of the stars missing (binomial: ~1500 stars, sd of the fraction ~0.011).
  EXPECT_NEAR(1.0 - static_cast<double>(seen) / missing_ref, 0.25, 0.04);
  // False objects' magnitudes follow the catalog's (V <= 6) distribution: quartiles agree.
  for (const auto& st : Bsc().stars)
    if (st.mag <= o.mag_max) star_mag.push_back(st.mag);
  std::sort(false_mag.begin(), false_mag.end());
  std::sort(star_mag.begin(), star_mag.end());
  for (double qtl : {0.25, 0.5, 0.75}) {
    EXPECT_NEAR(false_mag[static_cast<size_t>(qtl * false_mag.size())],
                star_mag[static_cast<size_t>(qtl * star_mag.size())], 0.1)
        << "quantile " << qtl;
  }
}

// Photometric noise: the same positions as without it (its own random stream), and the fluxes'
// magnitude residuals against the truth have the requested sigma.
TEST(SceneSim, FluxNoiseKeepsPositionsAndHasItsSigma) {
  SceneSimOptions o;
  o.false_objects_max = 40;
  SceneSimOptions noisy = o;
  noisy.flux_noise_mag = 0.3;
  double sum = 0, sum_sq = 0;
  int n = 0;
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    const SimulatedScene a = SimulateScene(Kelvins(), Bsc(), RandomAttitude(seed), o, seed);
    const SimulatedScene b = SimulateScene(Kelvins(), Bsc(), RandomAttitude(seed), noisy, seed);
    ASSERT_EQ(a.centroids.size(), b.centroids.size());
    for (size_t i = 0; i < a.centroids.size(); ++i) {
      EXPECT_EQ(a.centroids[i].x_px, b.centroids[i].x_px);
      EXPECT_EQ(a.centroids[i].y_px, b.centroids[i].y_px);
      EXPECT_NEAR(a.centroids[i].flux, std::pow(10.0, -0.4 * a.mag[i]), 1e-12);
      const double dm = -2.5 * std::log10(b.centroids[i].flux) - b.mag[i];
      sum += dm, sum_sq += dm * dm, ++n;
    }
  }
  ASSERT_GT(n, 300);
  EXPECT_NEAR(sum / n, 0.0, 0.06);
  EXPECT_NEAR(std::sqrt(sum_sq / n), 0.3, 0.04);
  noisy.flux_noise_mag = -1;
  EXPECT_THROW(SimulateScene(Kelvins(), Bsc(), RandomAttitude(1), noisy, 1), InputError);
}

TEST(SceneSim, CsvRoundTripsThroughTheSolverReader) {
  SceneSimOptions o;
  o.false_objects_min = o.false_objects_max = 12;
  const SimulatedScene s = SimulateScene(Kelvins(), Bsc(), RandomAttitude(3), o, 3);
  const std::string path = testing::TempDir("scene_csv") + "/scene.csv";
  WriteSceneCsv(path, s);
  const std::vector<Centroid> back = ReadCentroidsCsv(path);
  ASSERT_EQ(back.size(), s.centroids.size());
  for (size_t i = 0; i < back.size(); ++i) {
    EXPECT_NEAR(back[i].x_px, s.centroids[i].x_px, 1e-8);
    EXPECT_NEAR(back[i].y_px, s.centroids[i].y_px, 1e-8);
    EXPECT_NEAR(back[i].flux, s.centroids[i].flux, 1e-8 * s.centroids[i].flux);
    EXPECT_NEAR(back[i].sigma_px, s.centroids[i].sigma_px, 1e-12);
  }
}

TEST(SceneSim, BadOptionsNameTheField) {
  SceneSimOptions o;
  o.false_objects_min = 5;
  o.false_objects_max = 2;
  try {
    o.Check();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("false_objects_max"), std::string::npos);
  }
  o = SceneSimOptions{};
  o.missing_fraction = 1.5;
  EXPECT_THROW(o.Check(), InputError);
}

TEST(SceneSim, SimulateFrameWritesCentroidLists) {
  const std::string dir = testing::TempDir("scene_cli");
  const auto r = testing::RunSsiu(
      "simulate frame --centroids-only --random --seed 5 --count 3 --false-objects 10,20 "
      "--missing-fraction 0 --centroid-noise-px 0.1 --out " +
      dir);
  ASSERT_EQ(r.status, 0) << r.output;
  for (int k = 0; k < 3; ++k) {
    char name[64];
    std::snprintf(name, sizeof(name), "/frame_%04d", k);
    const Json truth = ReadJsonFile(dir + name + ".json");
    const std::vector<Centroid> c = ReadCentroidsCsv(dir + name + "_centroids.csv");
    const int nf = truth["false_objects"].get<int>();
    EXPECT_GE(nf, 10);
    EXPECT_LE(nf, 20);
    EXPECT_EQ(static_cast<int>(c.size()), truth["true_stars"].get<int>() + nf);
    EXPECT_FALSE(std::ifstream(dir + name + ".png").good()) << "no frame rendered with --centroids-only";
  }
  EXPECT_NE(testing::RunSsiu("simulate frame --centroids-only --random --false-objects 1,2,3 --out " + dir).status, 0);
}

}  // namespace
}  // namespace ssiu
