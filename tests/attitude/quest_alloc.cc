// QUEST on one head's matches and the fusion of 1, 2 and 3 heads allocate nothing (the flight
// core's rule, issue 26). A program of its own (attitude_alloc_test): the counting operator new of
// testing/alloc_count.h counts every allocation of the process.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "attitude/quest.h"
#include "attitude/star_solver.h"
#include "core/astrometry.h"
#include "core/catalog.h"
#include "testing/alloc_count.h"

namespace ssiu {
namespace {

// A solved identification of `n` stars seen by a sensor at q_inertial_from_sensor, with noise of
// sigma_rad per axis on the measured directions.
Identification Matches(std::mt19937_64& rng, const Quat& q_sensor, int n, double sigma_rad, bool fitted) {
  std::normal_distribution<double> g(0, 1);
  Identification id;
  id.status = SolveStatus::kSolved;
  id.focal_length_fitted = fitted;
  id.false_match_probability = 1e-12;
  for (int i = 0; i < n; ++i) {
    const Vec3 b = Vec3(0.12 * g(rng), 0.12 * g(rng), 1.0).normalized();
    StarMatch m;
    m.r_inertial = q_sensor * b;
    m.b_sensor = (b + sigma_rad * Vec3(g(rng), g(rng), g(rng))).normalized();
    m.sigma_rad = sigma_rad;
    id.matches.push_back(m);
  }
  return id;
}

double AngleRad(const Quat& a, const Quat& b) { return a.angularDistance(b); }

const Quat kMount[3] = {Quat::Identity(), Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitX())),
                        Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitY()))};

TEST(QuestAlloc, OneTwoAndThreeHeadsAllocateNothing) {
  std::mt19937_64 rng(26);
  constexpr double kSigma = 5e-5;
  for (int t = 0; t < 4; ++t) {
    const Quat q_body(Eigen::AngleAxisd(0.7 + t, Vec3(1, -2, 0.5 + t).normalized()));
    std::vector<Identification> ids;
    std::vector<Quat> mounts;
    for (int h = 0; h < 3; ++h) {
      ids.push_back(Matches(rng, q_body * kMount[h], 12 + 4 * h, kSigma, (t + h) % 2 == 0));
      mounts.push_back(kMount[h]);
    }
    for (size_t heads = 1; heads <= 3; ++heads) {
      const std::vector<Identification> id(ids.begin(), ids.begin() + heads);
      const std::vector<Quat> m(mounts.begin(), mounts.begin() + heads);
      const MultiHeadSolution ref = SolveMultiHeadChecked(id, m);  // the allocating form
      MultiHeadSolution out;
      out.head_use.reserve(3);
      out.q_inertial_from_body_per_head.reserve(3);
      AttitudeSolution single, fused;
      testing::AllocationCounter n;
      single = SolveAttitude(id[heads - 1]);
      fused = SolveMultiHead(id, m);
      SolveMultiHeadChecked(id, m, MultiHeadOptions{}, &out, /*diagnostics=*/false);
      EXPECT_EQ(n.Count(), 0) << heads << " heads: " << n.Bytes() << " bytes";
      ASSERT_EQ(single.status, SolveStatus::kSolved);
      ASSERT_EQ(fused.status, SolveStatus::kSolved);
      // Against the truth: the attitude within 5 of its reported sigmas.
      const double sigma = std::sqrt(fused.covariance_rad2.trace());
      EXPECT_LT(AngleRad(fused.q_inertial_from_sensor, q_body), 5 * sigma);
      EXPECT_LT(AngleRad(single.q_inertial_from_sensor, q_body * kMount[heads - 1]),
                5 * std::sqrt(single.covariance_rad2.trace()));
      // The caller-storage and allocating forms give the same answer.
      EXPECT_EQ(fused.q_inertial_from_sensor.coeffs(), ref.attitude.q_inertial_from_sensor.coeffs());
      EXPECT_EQ(out.attitude.q_inertial_from_sensor.coeffs(), ref.attitude.q_inertial_from_sensor.coeffs());
      EXPECT_EQ(out.attitude.covariance_rad2, ref.attitude.covariance_rad2);
      EXPECT_EQ(out.head_use, ref.head_use);
      EXPECT_FALSE(out.input_error);
      EXPECT_TRUE(out.message.empty());
      EXPECT_FALSE(ref.message.empty());
    }
  }
}

TEST(QuestAlloc, InconsistentHeadAndBadInputAllocateNothing) {
  std::mt19937_64 rng(27);
  const Quat q_body(Eigen::AngleAxisd(2.0, Vec3(0.3, 0.4, -1).normalized()));
  std::vector<Identification> ids;
  std::vector<Quat> mounts(kMount, kMount + 3);
  for (int h = 0; h < 3; ++h) ids.push_back(Matches(rng, q_body * kMount[h], 15, 5e-5, false));
  mounts[2] = Quat(Eigen::AngleAxisd(0.02, Vec3::UnitZ())) * mounts[2];  // head 3's mount is wrong by 1.1 deg
  MultiHeadSolution out;
  out.head_use.reserve(3);
  out.q_inertial_from_body_per_head.reserve(3);
  MultiHeadOptions bad;
  bad.consistency_sigmas = -1;
  const std::vector<Quat> two_mounts(kMount, kMount + 2);
  {
    testing::AllocationCounter n;
    SolveMultiHeadChecked(ids, mounts, MultiHeadOptions{}, &out, false);
    EXPECT_EQ(n.Count(), 0);
  }
  EXPECT_EQ(out.attitude.status, SolveStatus::kSolved);
  EXPECT_EQ(out.head_use, (std::vector<HeadUse>{HeadUse::kUsed, HeadUse::kUsed, HeadUse::kInconsistent}));
  {
    testing::AllocationCounter n;
    SolveMultiHeadChecked(ids, two_mounts, MultiHeadOptions{}, &out, false);
    EXPECT_EQ(n.Count(), 0);
  }
  EXPECT_TRUE(out.input_error);
  {
    testing::AllocationCounter n;
    SolveMultiHeadChecked(ids, mounts, bad, &out, false);
    EXPECT_EQ(n.Count(), 0);
  }
  EXPECT_TRUE(out.input_error);
  EXPECT_EQ(out.attitude.status, SolveStatus::kNoMatch);
}

TEST(QuestAlloc, CentroidsIntoAReservedVectorAllocateNothing) {
  Detections d;
  for (int i = 0; i < 40; ++i) {
    StarDetection s;
    s.x_px = 10.5 * i;
    s.y_px = 3.25 * i;
    s.flux_adu = 1000 - i;
    s.x_sigma_px = 0.01 * (i + 1);
    s.y_sigma_px = 0.02 * (i + 1);
    d.stars.push_back(s);
  }
  std::vector<Centroid> c;
  c.reserve(64);
  {
    testing::AllocationCounter n;
    CentroidsFromDetections(d, 1.5, &c);
    CentroidsFromDetections(d, 1.5, &c);
    EXPECT_EQ(n.Count(), 0);
  }
  ASSERT_EQ(c.size(), 40u);
  // sigma_px = scale * rms of the two axes' sigmas.
  EXPECT_DOUBLE_EQ(c[3].sigma_px, 1.5 * std::sqrt(0.5 * (0.04 * 0.04 + 0.08 * 0.08)));
  EXPECT_EQ(c[7].x_px, 73.5);
}

// What the unit's processor calls after identification: the sky corrections of the matches (proper
// motion to the frame's date, aberration) allocate nothing, inactive (no time) or active.
TEST(QuestAlloc, SkyCorrectionsAllocateNothing) {
  CatalogBuildOptions co;
  co.fov_deg = 20;
  const StarIdentifier id(BuildSolverCatalog(LoadXplanetBsc(DefaultBscPath(), 5.0), co));
  Identification ident;
  ident.status = SolveStatus::kSolved;
  for (int s = 0; s < 40; ++s) {
    StarMatch m;
    m.star = s;
    m.r_inertial = id.catalog().stars[s].unit;
    ident.matches.push_back(m);
  }
  SkyCorrections sky;
  {
    testing::AllocationCounter n;
    ApplySkyCorrections(id, sky, &ident);
    EXPECT_EQ(n.Count(), 0);
  }
  EXPECT_EQ(ident.matches[3].r_inertial, id.catalog().stars[3].unit);
  sky.time = ParseUtcIso8601("2026-03-20T09:01:00Z", "t");
  sky.have_velocity = true;
  sky.velocity_m_s = Vec3(2e3, -7e3, 1.5e3);
  testing::AllocationCounter n;
  ApplySkyCorrections(id, sky, &ident);
  EXPECT_EQ(n.Count(), 0);
  EXPECT_EQ(n.Exceptions(), 0);
  // Moved by the aberration (~20 arcsec), not by more than a few arcmin.
  const double moved = ident.matches[3].r_inertial.cross(id.catalog().stars[3].unit).norm();
  EXPECT_GT(moved, 1e-5);
  EXPECT_LT(moved, 1e-3);
}

}  // namespace
}  // namespace ssiu
