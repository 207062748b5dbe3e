// Identify and MatchWithAttitude in their workspace forms allocate nothing and throw nothing once the
// workspace is built (the flight core's rule, issue 26), on synthetic frames with a known attitude:
// lost in space that solves, random centroids (no match), tracking and lost lock, the focal length
// searched, more centroids or catalog stars than the workspace holds, non-finite centroids. A program
// of its own (identify_alloc_test): the counting operator new of testing/alloc_count.h counts every
// allocation of the process.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/attitude.h"
#include "core/error.h"
#include "core/rng.h"
#include "identify/identify.h"
#include "identify/synthetic.h"
#include "testing/alloc_count.h"

namespace ssiu {
namespace {

using testing::AllocationCounter;
using testing::Bsc166;
using testing::MakeSyntheticFrame;
using testing::SyntheticFrame;
using testing::SyntheticOptions;

const Camera& Cam() {
  static const Camera cam = MakeCamera(1024, 1024, 16.6);
  return cam;
}

SyntheticFrame Frame(uint64_t seed, Quat* q) {
  Rng rng(seed);
  *q = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform());
  return MakeSyntheticFrame(Bsc166().catalog(), Cam(), *q, SyntheticOptions{}, &rng);
}

// One workspace call under the allocation counter: no allocation, no exception.
template <typename Call>
SolveStatus Counted(Call&& call) {
  AllocationCounter n;
  const SolveStatus s = call();
  EXPECT_EQ(n.Count(), 0) << n.Bytes() << " bytes";
  EXPECT_EQ(n.Exceptions(), 0);
  return s;
}

// Every match is the frame's truth for its (input) centroid.
void ExpectTrueMatches(const Identification& r, const SyntheticFrame& f) {
  for (const StarMatch& m : r.matches) {
    ASSERT_GE(m.centroid, 0);
    ASSERT_LT(m.centroid, static_cast<int>(f.truth_id.size()));
    EXPECT_EQ(f.truth_id[m.centroid], m.star_id);
  }
}

void ExpectSameAnswer(const Identification& a, const Identification& b) {
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.q_inertial_from_sensor.coeffs(), b.q_inertial_from_sensor.coeffs());
  EXPECT_EQ(a.false_match_probability, b.false_match_probability);
  EXPECT_EQ(a.hypotheses, b.hypotheses);
  ASSERT_EQ(a.matches.size(), b.matches.size());
  for (size_t i = 0; i < a.matches.size(); ++i) {
    EXPECT_EQ(a.matches[i].centroid, b.matches[i].centroid);
    EXPECT_EQ(a.matches[i].star, b.matches[i].star);
  }
}

struct Flight {
  IdentifyWorkspace ws{200, 800};
  Identification out;
  Flight() { ws.Reserve(&out); }
};

TEST(IdentifyAlloc, LostInSpaceSolvesWithoutAllocating) {
  const StarIdentifier& id = Bsc166();
  Flight fl;
  EXPECT_TRUE(fl.out.matches.capacity() >= 200);
  for (int i = 0; i < 12; ++i) {
    Quat q;
    const SyntheticFrame f = Frame(2600 + i, &q);
    const SolveStatus s = Counted([&] { return id.Identify(f.centroids, Cam(), IdentifyOptions{}, &fl.ws, &fl.out); });
    ASSERT_EQ(s, SolveStatus::kSolved) << "frame " << i;
    EXPECT_EQ(fl.out.status, s);
    EXPECT_LT(AttitudeErrorRad(fl.out.q_inertial_from_sensor, q) * kRadToArcsec, 60);
    EXPECT_GE(fl.out.matches.size(), 4u);
    ExpectTrueMatches(fl.out, f);
    EXPECT_TRUE(fl.out.message.empty());
    EXPECT_TRUE(fl.out.timing_ms.empty());
    EXPECT_FALSE(fl.out.centroids_clamped || fl.out.stars_clamped || fl.out.input_error);
    AllocationCounter by_value;  // the counter counts: the by-value form allocates
    const Identification ref = id.Identify(f.centroids, Cam(), IdentifyOptions{});
    EXPECT_GT(by_value.Count(), 0);
    ExpectSameAnswer(fl.out, ref);
  }
}

TEST(IdentifyAlloc, RandomCentroidsAreNoMatchWithoutAllocating) {
  const StarIdentifier& id = Bsc166();
  Flight fl;
  for (int i = 0; i < 4; ++i) {
    Rng rng(77 + i);
    std::vector<Centroid> c(30);
    for (auto& x : c) x = {rng.Uniform(0, 1023), rng.Uniform(0, 1023), rng.Uniform(), 0.3};
    EXPECT_EQ(Counted([&] { return id.Identify(c, Cam(), IdentifyOptions{}, &fl.ws, &fl.out); }),
              SolveStatus::kNoMatch);
    EXPECT_EQ(fl.out.stop, SearchStop::kExhausted);
    EXPECT_TRUE(fl.out.matches.empty());
  }
  // Too few: a status too.
  const std::vector<Centroid> three = {{100, 100, 1, 0.2}, {500, 300, 1, 0.2}, {900, 800, 1, 0.2}};
  EXPECT_EQ(Counted([&] { return id.Identify(three, Cam(), IdentifyOptions{}, &fl.ws, &fl.out); }),
            SolveStatus::kTooFewStars);
}

TEST(IdentifyAlloc, TrackingAndLostLockWithoutAllocating) {
  const StarIdentifier& id = Bsc166();
  Flight fl;
  for (int i = 0; i < 8; ++i) {
    Quat q;
    const SyntheticFrame f = Frame(2700 + i, &q);
    const Quat q_pred = q * Quat(Eigen::AngleAxisd(0.1 * kDegToRad, Vec3(1, 1, 0).normalized()));
    ASSERT_EQ(Counted([&] {
                return id.MatchWithAttitude(f.centroids, Cam(), q_pred, 30.0, IdentifyOptions{}, &fl.ws, &fl.out);
              }),
              SolveStatus::kSolved);
    EXPECT_LT(SplitAttitudeError(fl.out.q_inertial_from_sensor, q).cross_rad * kRadToArcsec, 10);
    ExpectTrueMatches(fl.out, f);
    ExpectSameAnswer(fl.out, id.MatchWithAttitude(f.centroids, Cam(), q_pred, 30.0, IdentifyOptions{}));
    const Quat q_far = q * Quat(Eigen::AngleAxisd(3 * kDegToRad, Vec3::UnitX()));
    EXPECT_EQ(Counted([&] {
                return id.MatchWithAttitude(f.centroids, Cam(), q_far, 5.0, IdentifyOptions{}, &fl.ws, &fl.out);
              }),
              SolveStatus::kNoMatch);
    // A prediction of NaN: lost, not a crash.
    const Quat q_nan(std::nan(""), 0, 0, 0);
    EXPECT_EQ(Counted([&] {
                return id.MatchWithAttitude(f.centroids, Cam(), q_nan, 30.0, IdentifyOptions{}, &fl.ws, &fl.out);
              }),
              SolveStatus::kNoMatch);
  }
}

TEST(IdentifyAlloc, FocalLengthSearchedWithoutAllocating) {
  const StarIdentifier& id = Bsc166();
  Flight fl;
  Camera guess = Cam();
  guess.focal_length_px *= 1.04;
  IdentifyOptions io;
  io.fov_tolerance_pct = 6;
  for (int i = 0; i < 4; ++i) {
    Quat q;
    const SyntheticFrame f = Frame(2800 + i, &q);
    ASSERT_EQ(Counted([&] { return id.Identify(f.centroids, guess, io, &fl.ws, &fl.out); }), SolveStatus::kSolved);
    EXPECT_NEAR(fl.out.focal_length_px, Cam().focal_length_px, 0.002 * Cam().focal_length_px);
    EXPECT_LT(SplitAttitudeError(fl.out.q_inertial_from_sensor, q).cross_rad * kRadToArcsec, 10);
    ExpectTrueMatches(fl.out, f);
  }
}

// 300 faint false centroids after the frame's: the 200 brightest are used (the stars among them),
// flagged; the match indices are the input's.
TEST(IdentifyAlloc, TooManyCentroidsUsesTheBrightest) {
  const StarIdentifier& id = Bsc166();
  Flight fl;
  for (int i = 0; i < 4; ++i) {
    Quat q;
    SyntheticFrame f = Frame(2900 + i, &q);
    Rng rng(3900 + i);
    std::vector<Centroid> c;
    std::vector<StarId> truth;
    for (int k = 0; k < 300; ++k) {  // the faint ones first in the input
      c.push_back({rng.Uniform(0, 1023), rng.Uniform(0, 1023), 1e-6 * rng.Uniform(), 0.2});
      truth.push_back(kInvalidStarId);
    }
    c.insert(c.end(), f.centroids.begin(), f.centroids.end());
    truth.insert(truth.end(), f.truth_id.begin(), f.truth_id.end());
    f.centroids = c;
    f.truth_id = truth;
    ASSERT_EQ(Counted([&] { return id.Identify(f.centroids, Cam(), IdentifyOptions{}, &fl.ws, &fl.out); }),
              SolveStatus::kSolved);
    EXPECT_TRUE(fl.out.centroids_clamped);
    EXPECT_LT(AttitudeErrorRad(fl.out.q_inertial_from_sensor, q) * kRadToArcsec, 60);
    ExpectTrueMatches(fl.out, f);
    for (const StarMatch& m : fl.out.matches) EXPECT_GE(m.centroid, 300);
    const Quat q_pred = q * Quat(Eigen::AngleAxisd(0.1 * kDegToRad, Vec3::UnitY()));
    ASSERT_EQ(Counted([&] {
                return id.MatchWithAttitude(f.centroids, Cam(), q_pred, 30.0, IdentifyOptions{}, &fl.ws, &fl.out);
              }),
              SolveStatus::kSolved);
    EXPECT_TRUE(fl.out.centroids_clamped);
    ExpectTrueMatches(fl.out, f);
  }
}

// Room for 20 verification centroids where the options ask for 150: the 20 brightest verify, flagged;
// the frame still solves to its truth without allocating.
TEST(IdentifyAlloc, FewerVerificationCentroidsThanAskedAreFlagged) {
  const StarIdentifier& id = Bsc166();
  IdentifyWorkspace ws(200, 800, 100, 20);
  Identification out;
  ws.Reserve(&out);
  Quat q;
  const SyntheticFrame f = Frame(4100, &q);
  ASSERT_GT(f.centroids.size(), 20u);
  IdentifyOptions o;
  o.pattern_centroids = 15;
  ASSERT_EQ(Counted([&] { return id.Identify(f.centroids, Cam(), o, &ws, &out); }), SolveStatus::kSolved);
  EXPECT_TRUE(out.centroids_clamped);
  EXPECT_LE(out.matches.size(), 20u);
  EXPECT_LT(AttitudeErrorRad(out.q_inertial_from_sensor, q) * kRadToArcsec, 60);
  ExpectTrueMatches(out, f);
}

// Room for 30 catalog stars about the field (a 16.6-deg field has ~100): the brightest, flagged.
TEST(IdentifyAlloc, TooManyStarsInTheFieldUsesTheBrightest) {
  const StarIdentifier& id = Bsc166();
  IdentifyWorkspace ws(200, 30);
  Identification out;
  ws.Reserve(&out);
  int solved = 0;
  for (int i = 0; i < 6; ++i) {
    Quat q;
    const SyntheticFrame f = Frame(3000 + i, &q);
    if (Counted([&] { return id.Identify(f.centroids, Cam(), IdentifyOptions{}, &ws, &out); }) ==
        SolveStatus::kSolved) {
      ++solved;
      EXPECT_LT(AttitudeErrorRad(out.q_inertial_from_sensor, q) * kRadToArcsec, 60);
      ExpectTrueMatches(out, f);
    }
    EXPECT_TRUE(out.stars_clamped);
  }
  EXPECT_GE(solved, 4);
}

TEST(IdentifyAlloc, NonFiniteCentroidsAreSkipped) {
  const StarIdentifier& id = Bsc166();
  Flight fl;
  for (int i = 0; i < 4; ++i) {
    Quat q;
    SyntheticFrame f = Frame(3100 + i, &q);
    const double nan = std::nan(""), inf = INFINITY;
    f.centroids[1].x_px = nan;
    f.centroids[3].y_px = inf;
    f.centroids[5].flux = nan;
    f.centroids[6].sigma_px = nan;
    f.centroids[8].sigma_px = -1;
    ASSERT_EQ(Counted([&] { return id.Identify(f.centroids, Cam(), IdentifyOptions{}, &fl.ws, &fl.out); }),
              SolveStatus::kSolved);
    EXPECT_EQ(fl.out.centroids_skipped, 5);
    EXPECT_LT(AttitudeErrorRad(fl.out.q_inertial_from_sensor, q) * kRadToArcsec, 60);
    ExpectTrueMatches(fl.out, f);
    for (const StarMatch& m : fl.out.matches) EXPECT_TRUE(std::isfinite(m.x_px) && std::isfinite(m.y_px));
    const Quat q_pred = q * Quat(Eigen::AngleAxisd(0.1 * kDegToRad, Vec3::UnitY()));
    ASSERT_EQ(Counted([&] {
                return id.MatchWithAttitude(f.centroids, Cam(), q_pred, 30.0, IdentifyOptions{}, &fl.ws, &fl.out);
              }),
              SolveStatus::kSolved);
    EXPECT_EQ(fl.out.centroids_skipped, 5);
    ExpectTrueMatches(fl.out, f);
  }
  std::vector<Centroid> all_nan(20, Centroid{std::nan(""), 1, 1, 0.2});
  EXPECT_EQ(Counted([&] { return id.Identify(all_nan, Cam(), IdentifyOptions{}, &fl.ws, &fl.out); }),
            SolveStatus::kTooFewStars);
  EXPECT_EQ(fl.out.centroids_skipped, 20);
}

// With diagnostics the result carries the by-value form's message and timing (allocating).
TEST(IdentifyAlloc, DiagnosticsGiveTheMessage) {
  const StarIdentifier& id = Bsc166();
  Flight fl;
  fl.ws.diagnostics = true;
  Quat q;
  const SyntheticFrame f = Frame(3200, &q);
  ASSERT_EQ(id.Identify(f.centroids, Cam(), IdentifyOptions{}, &fl.ws, &fl.out), SolveStatus::kSolved);
  const Identification ref = id.Identify(f.centroids, Cam(), IdentifyOptions{});
  EXPECT_EQ(fl.out.message, ref.message);
  EXPECT_EQ(fl.out.timing_ms.count("identify"), 1u);
  ExpectSameAnswer(fl.out, ref);
}

// Bytes() is what construction allocates; 200 x 800 is mostly the match candidates (200 x 800 x 16).
TEST(IdentifyAlloc, BytesAreWhatConstructionAllocates) {
  AllocationCounter n;
  const IdentifyWorkspace ws(200, 800);
  const long allocated = n.Bytes();
  EXPECT_GE(static_cast<long>(ws.Bytes()), allocated - 64);
  EXPECT_LE(static_cast<long>(ws.Bytes()), allocated + 1024);
  // The match candidates: the 150 verification centroids (max_verify_centroids) against 800 stars.
  EXPECT_GT(ws.Bytes(), 150u * 800 * 16);
  EXPECT_LT(ws.Bytes(), 150u * 800 * 16 + 400000);
  EXPECT_EQ(ws.max_verify_centroids(), 150);
  std::printf("IdentifyWorkspace(200, 800): %zu bytes; (100, 400): %zu; (1000, 2000): %zu\n", ws.Bytes(),
              IdentifyWorkspace(100, 400).Bytes(), IdentifyWorkspace(1000, 2000).Bytes());
  EXPECT_THROW(IdentifyWorkspace(0, 800), InputError);
  EXPECT_THROW(IdentifyWorkspace(200, 800, 2), InputError);
  EXPECT_THROW(IdentifyWorkspace(200, 800, 100, 2), InputError);
}

}  // namespace
}  // namespace ssiu
