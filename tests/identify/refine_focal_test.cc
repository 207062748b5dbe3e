// A fixed focal length refined by default (IdentifyOptions::refine_focal_p): a camera.json off by a
// few tenths of a percent is absorbed, a right one keeps its numbers, and the scale test's p-values
// are those of a test (uniform when the camera is right). Truth: synthetic centroids projected with
// a known camera and attitude (identify/synthetic.h).
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/attitude.h"
#include "core/error.h"
#include "core/rng.h"
#include "identify/identify.h"
#include "identify/synthetic.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using testing::Bsc166;
using testing::MakeSyntheticFrame;
using testing::SyntheticOptions;

// A synthetic frame seen with `truth` at a random attitude (*q, from `seed`), identified with `given`.
Identification SolveSynthetic(const StarIdentifier& id, const Camera& truth, const Camera& given,
                              const IdentifyOptions& io, uint64_t seed, Quat* q) {
  Rng rng(seed);
  *q = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform());
  const auto f = MakeSyntheticFrame(id.catalog(), truth, *q, SyntheticOptions{}, &rng);
  return id.Identify(f.centroids, given, io);
}

TEST(RefineFocal, AFewTenthsOfAPercentAreAbsorbed) {
  const StarIdentifier& id = Bsc166();
  const Camera truth = MakeCamera(1024, 1024, 16.6);
  for (const double off : {+0.003, -0.003}) {
    Camera given = truth;
    given.ScaleFocal(1 + off);
    IdentifyOptions io;
    io.systematic_px = 0;
    IdentifyOptions fixed = io;
    fixed.refine_focal_p = 0;
    int solved = 0, refined = 0, within_3_sigma = 0;
    double cross_refined = 0, cross_fixed = 0;
    for (int i = 0; i < 10; ++i) {
      Rng rng(2700 + i);
      const Quat q = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform());
      const auto f = MakeSyntheticFrame(id.catalog(), truth, q, SyntheticOptions{}, &rng);
      const Identification r = id.Identify(f.centroids, given, io);
      const Identification r0 = id.Identify(f.centroids, given, fixed);
      if (r.status != SolveStatus::kSolved || r0.status != SolveStatus::kSolved) continue;
      ++solved;
      EXPECT_FALSE(r0.focal_length_refined);
      EXPECT_EQ(r0.focal_length_px, given.focal_length_px);
      if (!r.focal_length_refined) continue;
      ++refined;
      EXPECT_TRUE(r.focal_length_fitted);
      EXPECT_LT(r.focal_length_p_value, io.refine_focal_p);
      ASSERT_GT(r.focal_length_sigma_px, 0);
      within_3_sigma += std::abs(r.focal_length_px - truth.focal_length_px) < 3 * r.focal_length_sigma_px;
      EXPECT_GE(r.matches.size(), r0.matches.size()) << "frame " << i;
      cross_refined += SplitAttitudeError(r.q_inertial_from_sensor, q).cross_rad * kRadToArcsec;
      cross_fixed += SplitAttitudeError(r0.q_inertial_from_sensor, q).cross_rad * kRadToArcsec;
    }
    EXPECT_GE(solved, 9) << "off " << off;
    EXPECT_EQ(refined, solved) << "off " << off;
    EXPECT_GE(within_3_sigma, refined - 1) << "off " << off;
    // A wrong scale turns stars off-centre into a tilt of the fit (cross-boresight error).
    EXPECT_LT(cross_refined, 0.5 * cross_fixed) << "off " << off;
    std::printf("focal length %+.1f%%: refined %d of %d, within 3 sigma %d, mean cross error %.2f vs %.2f arcsec\n",
                off * 100, refined, solved, within_3_sigma, cross_refined / std::max(1, refined),
                cross_fixed / std::max(1, refined));
  }
}

TEST(RefineFocal, ARightCameraKeepsItsNumbersAndThePValuesAreUniform) {
  const StarIdentifier& id = Bsc166();
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  IdentifyOptions io;
  io.systematic_px = 0;
  int solved = 0, refined = 0, below_5pct = 0, below_half = 0;
  for (int i = 0; i < 200; ++i) {
    Quat q;
    const Identification r = SolveSynthetic(id, cam, cam, io, 9100 + i, &q);
    if (r.status != SolveStatus::kSolved) continue;
    ++solved;
    ASSERT_TRUE(std::isfinite(r.focal_length_p_value));
    below_5pct += r.focal_length_p_value < 0.05;
    below_half += r.focal_length_p_value < 0.5;
    if (r.focal_length_refined) {
      ++refined;
    } else {
      EXPECT_EQ(r.focal_length_px, cam.focal_length_px);
      EXPECT_FALSE(r.focal_length_fitted);
    }
  }
  std::printf("%d solved: refined %d, p < 0.05 in %d, p < 0.5 in %d\n", solved, refined, below_5pct, below_half);
  ASSERT_GE(solved, 190);
  // Binomial bounds (p = 1e-3, 0.05, 0.5 over ~200 frames) at about 4 sigma.
  EXPECT_LE(refined, 3);
  EXPECT_LE(below_5pct, 25);
  EXPECT_GE(below_half, solved / 2 - 30);
  EXPECT_LE(below_half, solved / 2 + 30);
}

TEST(RefineFocal, OffKeepsTheFocalLengthAndTrackingNeverRefits) {
  const StarIdentifier& id = Bsc166();
  const Camera truth = MakeCamera(1024, 1024, 16.6);
  Camera given = truth;
  given.ScaleFocal(1.004);
  Rng rng(31);
  const Quat q = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform());
  const auto f = MakeSyntheticFrame(id.catalog(), truth, q, SyntheticOptions{}, &rng);
  IdentifyOptions off;
  off.refine_focal_p = 0;
  const Identification r = id.Identify(f.centroids, given, off);
  ASSERT_EQ(r.status, SolveStatus::kSolved);
  EXPECT_EQ(r.focal_length_px, given.focal_length_px);
  EXPECT_TRUE(std::isnan(r.focal_length_p_value));
  const Identification t = id.MatchWithAttitude(f.centroids, given, q, 25, IdentifyOptions{});
  ASSERT_EQ(t.status, SolveStatus::kSolved);
  EXPECT_EQ(t.focal_length_px, given.focal_length_px);
  EXPECT_FALSE(t.focal_length_refined);
  IdentifyOptions bad;
  bad.refine_focal_p = 1;
  EXPECT_THROW(bad.Check(), InputError);
}

// The principal point (IdentifyOptions::refine_principal_p): a camera.json whose principal point is
// the image centre while the lens's is 30 px away is refitted from one frame's stars (within 3 sigma
// of the truth, the attitude closer to the truth than with the centre kept); with the right camera the
// test's p-values are those of a test (about 5% below 0.05) and none falls below the threshold.
TEST(RefinePrincipalPoint, ThirtyPixelsOffCentreAreFoundAndARightCameraKeepsItsOwn) {
  const StarIdentifier& id = Bsc166();
  Camera truth = MakeCamera(1024, 1024, 16.6);
  truth.cx_px += 24, truth.cy_px -= 18;
  const Camera given = MakeCamera(1024, 1024, 16.6);
  IdentifyOptions io;
  io.systematic_px = 0;
  int tested = 0, refined = 0, within_3_sigma = 0, better = 0;
  for (int i = 0; i < 12; ++i) {
    Quat q;
    Identification r = SolveSynthetic(id, truth, given, io, 5300 + i, &q);
    if (r.status != SolveStatus::kSolved) continue;
    const double before_arcsec = SplitAttitudeError(r.q_inertial_from_sensor, q).cross_rad * kRadToArcsec;
    RetestPrincipalPoint(given, io, &r);
    if (!std::isfinite(r.principal_point_p_value)) continue;  // too few stars, or not across the field
    ++tested;
    if (!r.principal_point_refined) continue;
    ++refined;
    const double err_px = std::hypot(r.cx_px - truth.cx_px, r.cy_px - truth.cy_px);
    within_3_sigma += err_px < 3 * r.principal_point_sigma_px;
    better += SplitAttitudeError(r.q_inertial_from_sensor, q).cross_rad * kRadToArcsec < before_arcsec;
    EXPECT_EQ(FittedCamera(given, r).cx_px, r.cx_px);
  }
  std::printf("principal point 30 px off: tested %d, refined %d, within 3 sigma %d, attitude better %d\n", tested,
              refined, within_3_sigma, better);
  EXPECT_GE(tested, 9);
  EXPECT_GE(refined, tested - 1);
  EXPECT_GE(within_3_sigma, refined - 1);
  EXPECT_GE(better, refined - 1);

  int right_tested = 0, right_refined = 0, below_5pct = 0;
  for (int i = 0; i < 60; ++i) {
    Quat q;
    Identification r = SolveSynthetic(id, given, given, io, 6100 + i, &q);
    if (r.status != SolveStatus::kSolved) continue;
    RetestPrincipalPoint(given, io, &r);
    if (!std::isfinite(r.principal_point_p_value)) continue;
    ++right_tested;
    right_refined += r.principal_point_refined;
    below_5pct += r.principal_point_p_value < 0.05;
  }
  std::printf("right camera: tested %d, refined %d, p < 0.05 in %d\n", right_tested, right_refined, below_5pct);
  EXPECT_GE(right_tested, 40);
  EXPECT_EQ(right_refined, 0);
  EXPECT_LE(below_5pct, 8);  // binomial(50, 0.05): P(> 8) ~ 0.3%
}

}  // namespace
}  // namespace ssiu
