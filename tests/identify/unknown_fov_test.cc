// Unknown field of view (issue 14 item 3): a catalog for 8-25 deg and frames of 10-20 deg whose
// focal length the solver is not told. CI-sized; the campaign is tests/identify/unknown_fov_longtest.cc.
#include "unknown_fov.h"

#include <cmath>
#include <cstdio>
#include <memory>

#include "core/attitude.h"
#include "core/catalog.h"
#include "core/error.h"
#include "core/rng.h"
#include "identify/identify.h"
#include "identify/synthetic.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using namespace testing;

TEST(UnknownFov, CatalogSpansTheRange) {
  const SolverCatalog& cat = UnknownFovIdentifier().catalog();
  EXPECT_DOUBLE_EQ(cat.fov_min_deg, 8.0);
  EXPECT_DOUBLE_EQ(cat.fov_deg, 25.0);
  double longest = 0, shortest = 1e9;
  for (const auto& t : cat.triangles)
    longest = std::max<double>(longest, t.longest_rad), shortest = std::min<double>(shortest, t.longest_rad);
  EXPECT_LE(longest * kRadToDeg, 25.0 + 1e-6);
  EXPECT_GT(longest * kRadToDeg, 20.0) << "triangles for the widest fields";
  EXPECT_LT(shortest * kRadToDeg, 2.0) << "triangles for the narrowest fields";
}

// Frames of 10-20 deg (1024 x 768, stars to V 6, 10% missing, 3 false), the focal length unknown:
// all solved, none wrong, focal length within 0.2 % and within 5 of its reported sigmas.
TEST(UnknownFov, SolvesFramesOfUnknownFocalLength) {
  const UnknownFovCampaign c = RunUnknownFov(16, 300, UnknownFovOptions());
  std::printf(
      "unknown FOV 8-25 deg, 10-20 deg frames: %d/%d solved, %d wrong, worst focal error %.4f %% (%.1f sigma), "
      "median %.1f ms\n",
      c.solved, c.frames, c.wrong, c.worst_focal_pct, c.worst_focal_z, c.MedianMs());
  EXPECT_GE(c.solved, 15);
  EXPECT_EQ(c.wrong, 0);
  EXPECT_EQ(c.misidentified, 0);
  EXPECT_LT(c.worst_focal_pct, 0.2);
  EXPECT_LT(c.worst_focal_z, 5.0);
}

// Random centroids: every solve is false. At a loose threshold the observed rate stays below it.
TEST(UnknownFov, ChanceProbabilityIsCalibratedOnRandomCentroids) {
  IdentifyOptions io = UnknownFovOptions();
  io.max_false_match_prob = 0.05;
  io.pattern_centroids = 25;  // CI-sized searches (the sequential factor counts max_hypotheses)
  io.max_hypotheses = 5000;
  const Calibration c = RunUnknownFovRandom(60, 7000, io);
  std::printf("unknown FOV, random centroids at 0.05: %d of %d solved\n", c.false_solves, c.trials);
  // P(Binomial(60, 0.05) > 8) < 1%.
  EXPECT_LE(c.false_solves, 8);
}

TEST(UnknownFov, OptionsAndCatalogAreChecked) {
  const Camera cam = MakeCamera(1024, 768, 15);
  std::vector<Centroid> c(10, Centroid{100, 100, 1, 0.3});
  IdentifyOptions io;
  io.fov_min_deg = 25, io.fov_max_deg = 8;
  EXPECT_THROW(UnknownFovIdentifier().Identify(c, cam, io), InputError);
  io.fov_min_deg = 8, io.fov_max_deg = 25, io.fov_tolerance_pct = 5;
  EXPECT_THROW(UnknownFovIdentifier().Identify(c, cam, io), InputError);
  // A range wider than the catalog's.
  io.fov_tolerance_pct = 0, io.fov_min_deg = 4;
  EXPECT_THROW(UnknownFovIdentifier().Identify(c, cam, io), InputError);
}

}  // namespace
}  // namespace ssiu
