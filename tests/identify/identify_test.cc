#include "identify/identify.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include "core/attitude.h"
#include "core/catalog.h"
#include "core/error.h"
#include "core/rng.h"
#include "identify/synthetic.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using testing::Bsc166;
using testing::MakeSyntheticFrame;
using testing::SyntheticOptions;

TEST(BinomialTail, MatchesDirectSums) {
  EXPECT_NEAR(BinomialTail(3, 0.5, 2), 0.5, 1e-12);  // (3 + 1) / 8
  EXPECT_NEAR(BinomialTail(10, 0.1, 0), 1.0, 1e-12);
  EXPECT_NEAR(BinomialTail(10, 0.1, 1), 1 - std::pow(0.9, 10), 1e-12);
  EXPECT_NEAR(BinomialTail(5, 0.2, 5), std::pow(0.2, 5), 1e-15);
}

// The photometric e-value under the null (docs/identify.md, step 5): the search takes triangles
// brightest first, so given that the triangle's faintest vertex is the c-th brightest of the eight
// fluxes, every assignment of the fluxes to the triangle's three pairs, two extra matches and three
// other centroids that keeps it so is equally likely, and the mean of E over them must be exactly 1
// for every c (a larger mean would make chance matches pass more often than --max-false-prob says).
TEST(Photometry, EvidenceHasMeanOneOverEveryPermutation) {
  const std::vector<double> mags = {3.1, 4.7, 2.2, 5.0, 3.9};  // triangle, then the extras in test order
  std::vector<double> f = {1, 2, 3, 5, 8, 13, 21, 34};
  std::sort(f.begin(), f.end());
  double sum[9] = {0}, max_e = 0;
  int count[9] = {0}, n = 0;
  do {
    const double e = PhotometricEvidence({f[0], f[1], f[2], f[3], f[4]}, mags, {f[5], f[6], f[7]});
    const double faintest = std::min({f[0], f[1], f[2]});
    const int c = static_cast<int>(std::count_if(f.begin(), f.end(), [&](double x) { return x >= faintest; }));
    sum[c] += e, ++count[c], max_e = std::max(max_e, e), ++n;
  } while (std::next_permutation(f.begin(), f.end()));
  EXPECT_EQ(n, 40320);
  for (int c = 3; c <= 8; ++c) {
    ASSERT_GT(count[c], 0) << c;
    EXPECT_NEAR(sum[c] / count[c], 1.0, 1e-12) << "faintest vertex the " << c << "-th brightest";
  }
  EXPECT_GT(max_e, 10.0);  // and it can be large: the test has power
}

// Analytic cases. The triangle: p = the share of the T = 3 (c-1)(c-2) ordered triples of its faintest
// flux (the c-th brightest) and two brighter ones whose zero points ln f + 0.4 ln(10) V scatter no more
// than its own, e = 1 / (p H_T). Three fluxes that follow their magnitudes exactly (c = 3): only the
// identity scatters 0, p = 1/6;
// reversed: every triple scatters less, p = 1; magnitudes 2, 3, 3: the identity and the swap of the
// last two tie, p = 2/6. An extra match whose flux is exactly the predicted one among N candidates:
// e = the mean of N / (K H_N) and N / (K^2 S_N) with K = 1.
TEST(Photometry, EvidenceAnalyticCases) {
  const std::vector<double> mags = {2.0, 3.0, 4.0};
  auto flux = [](double v) { return std::pow(10.0, -0.4 * v); };
  auto harmonic = [](int t) {
    double h = 0;
    for (int k = 1; k <= t; ++k) h += 1.0 / k;
    return h;
  };
  const double h6 = harmonic(6);
  EXPECT_NEAR(PhotometricEvidence({flux(2), flux(3), flux(4)}, mags, {}), 6 / h6, 1e-12);
  EXPECT_NEAR(PhotometricEvidence({flux(4), flux(3), flux(2)}, mags, {}), 1 / h6, 1e-12);
  EXPECT_NEAR(PhotometricEvidence({flux(2), flux(3), flux(4)}, {2.0, 3.0, 3.0}, {}), 3 / h6, 1e-12);
  // Fourth pair at V 5 with its exact flux, four other centroids (V 0, 1, 8, 9) far from it: K = 1 of
  // N = 5. The triangle's faintest (V 4) is the 5th brightest: T = 3 x 4 x 3 = 36 triples of it and two
  // of V 0, 1, 2, 3, of which only 2-3-4 scatters 0 against V 2, 3, 4, so p = 1 / 36.
  const double h5 = harmonic(5);
  const double s5 = 1 + 1 / 4.0 + 1 / 9.0 + 1 / 16.0 + 1 / 25.0;
  EXPECT_NEAR(
      PhotometricEvidence({flux(2), flux(3), flux(4), flux(5)}, {2, 3, 4, 5}, {flux(0), flux(1), flux(8), flux(9)}),
      36 / harmonic(36) * 0.5 * (5 / h5 + 5 / s5), 1e-9);
  EXPECT_THROW(PhotometricEvidence({1, 2}, {1, 2}, {}), InputError);
}

TEST(Identify, SolvesSyntheticFramesWithFalseAndMissingStars) {
  const StarIdentifier& id = Bsc166();
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  IdentifyOptions io;
  io.systematic_px = 0.0;
  int solved = 0, wrong = 0, id_errors = 0;
  const int kFrames = 50;
  for (int i = 0; i < kFrames; ++i) {
    Rng rng(1000 + i);
    const Quat q = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform());
    const auto f = MakeSyntheticFrame(id.catalog(), cam, q, SyntheticOptions{}, &rng);
    const Identification r = id.Identify(f.centroids, cam, io);
    if (r.status != SolveStatus::kSolved) continue;
    ++solved;
    EXPECT_LT(r.false_match_probability, 1e-5);
    if (AttitudeErrorRad(r.q_inertial_from_sensor, q) * kRadToArcsec > 60) ++wrong;
    for (const auto& m : r.matches)
      if (f.truth_id[m.centroid] != m.star_id) ++id_errors;
  }
  EXPECT_GE(solved, 49) << "of " << kFrames;
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(id_errors, 0);
}

TEST(Identify, PureNoiseIsNeverSolved) {
  const StarIdentifier& id = Bsc166();
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  for (int i = 0; i < 10; ++i) {
    Rng rng(77 + i);
    std::vector<Centroid> c(30);
    for (auto& x : c) x = {rng.Uniform(0, 1023), rng.Uniform(0, 1023), rng.Uniform(), 0.3};
    const Identification r = id.Identify(c, cam, IdentifyOptions{});
    EXPECT_NE(r.status, SolveStatus::kSolved) << "noise frame " << i;
  }
}

TEST(Identify, TooFewStars) {
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  std::vector<Centroid> c = {{100, 100, 1, 0.2}, {500, 300, 1, 0.2}, {900, 800, 1, 0.2}};
  EXPECT_EQ(Bsc166().Identify(c, cam, IdentifyOptions{}).status, SolveStatus::kTooFewStars);
  EXPECT_EQ(Bsc166().Identify({}, cam, IdentifyOptions{}).status, SolveStatus::kTooFewStars);
}

TEST(Identify, NonFiniteCentroidIsInputError) {
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  std::vector<Centroid> c(6, Centroid{10, 10, 1, 0.2});
  c[3].x_px = std::nan("");
  EXPECT_THROW(Bsc166().Identify(c, cam, IdentifyOptions{}), InputError);
}

TEST(Identify, FindsFocalLengthWithinTolerance) {
  const StarIdentifier& id = Bsc166();
  const Camera truth = MakeCamera(1024, 1024, 16.6);
  Camera guess = truth;
  guess.focal_length_px *= 1.04;  // 4 % off
  IdentifyOptions io;
  io.fov_tolerance_pct = 6;
  int solved = 0;
  for (int i = 0; i < 10; ++i) {
    Rng rng(500 + i);
    const Quat q = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform());
    const auto f = MakeSyntheticFrame(id.catalog(), truth, q, SyntheticOptions{}, &rng);
    const Identification r = id.Identify(f.centroids, guess, io);
    if (r.status != SolveStatus::kSolved) continue;
    ++solved;
    // 0.2 px noise is 12 arcsec per star at 58 arcsec/px: boresight to a few arcsec, roll to ~30.
    EXPECT_NEAR(r.focal_length_px, truth.focal_length_px, 0.002 * truth.focal_length_px);
    EXPECT_LT(SplitAttitudeError(r.q_inertial_from_sensor, q).cross_rad * kRadToArcsec, 10);
    EXPECT_LT(AttitudeErrorRad(r.q_inertial_from_sensor, q) * kRadToArcsec, 90);
  }
  EXPECT_GE(solved, 9);
}

TEST(Identify, TrackingMatchesFromPredictedAttitude) {
  const StarIdentifier& id = Bsc166();
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  Rng rng(4242);
  const Quat q = QuatFromRaDecRoll(1.0, 0.3, 0.5);
  const auto f = MakeSyntheticFrame(id.catalog(), cam, q, SyntheticOptions{}, &rng);
  // Prediction 0.1 deg off: within a 30 px search radius (~0.5 deg) the tracker re-locks.
  const Quat q_pred = q * Quat(Eigen::AngleAxisd(0.1 * kDegToRad, Vec3(1, 1, 0).normalized()));
  const Identification r = id.MatchWithAttitude(f.centroids, cam, q_pred, 30.0, IdentifyOptions{});
  ASSERT_EQ(r.status, SolveStatus::kSolved) << r.message;
  // Same matches as a lost-in-space solve of the frame, hence the same attitude.
  const Identification lis = id.Identify(f.centroids, cam, IdentifyOptions{});
  ASSERT_EQ(lis.status, SolveStatus::kSolved);
  EXPECT_EQ(r.matches.size(), lis.matches.size());
  EXPECT_THAT(r.q_inertial_from_sensor, QuaternionNear(lis.q_inertial_from_sensor, 0.01));
  EXPECT_LT(SplitAttitudeError(r.q_inertial_from_sensor, q).cross_rad * kRadToArcsec, 10);
  // A prediction 3 deg off loses lock (reported, not a wrong attitude).
  const Quat q_far = q * Quat(Eigen::AngleAxisd(3 * kDegToRad, Vec3::UnitX()));
  EXPECT_EQ(id.MatchWithAttitude(f.centroids, cam, q_far, 5.0, IdentifyOptions{}).status, SolveStatus::kNoMatch);
}

}  // namespace
}  // namespace ssiu
