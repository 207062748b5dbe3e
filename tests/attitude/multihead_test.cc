// Multi-head fusion on simulated frames: a known body attitude and known mounts, one simulated and
// detected frame per head, each solved lost in space, then fused in body axes.
#include <cmath>
#include <cstdio>
#include <memory>

#include "attitude/quest.h"
#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/catalog.h"
#include "core/error.h"
#include "sim/frame_sim.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// Error rotation in body axes: q_est = q_true * [1, dtheta / 2].
Vec3 BodyError(const Quat& q_est, const Quat& q_true) {
  Quat d = q_true.conjugate() * q_est;
  if (d.w() < 0) d.coeffs() = -d.coeffs();
  return 2 * d.vec();
}

struct Rig {
  StarCatalog sky = LoadXplanetBsc(DefaultBscPath(), 7.0);
  Camera cam = MakeCamera(1024, 1024, 16.6);
  std::unique_ptr<StarIdentifier> id;
  Rig() {
    CatalogBuildOptions co;
    co.fov_deg = 16.6;
    id = std::make_unique<StarIdentifier>(BuildSolverCatalog(sky, co));
  }
  // Simulates and solves head `mount`'s frame for body attitude q_body (inertial <- body).
  Identification Solve(const Quat& q_body, const Quat& mount, uint64_t seed, FrameSimOptions fo = {}) const {
    const Quat q_sensor = q_body * mount;  // inertial <- body <- sensor
    const SimulatedFrame sf = SimulateFrame(cam, sky, q_sensor, fo, seed);
    SolveOptions so;
    so.identify.systematic_px = 0;  // simulated optics: the fit's sigma is all
    DetectOptions d = so.detect;
    d.gain_e_per_adu = fo.gain_e_per_adu;
    return SolveCentroids(*id, CentroidsFromDetections(Detect(sf.image.view(), d), so.detector_sigma_scale), cam, so)
        .identification;
  }
};

const Rig& TheRig() {
  static const Rig rig;
  return rig;
}

// Mounts (sensor -> body): head 0 along body +Z, head 1 turned 90 deg about body X (looks along
// body -Y), head 2 turned 90 deg about body Y (looks along body +X).
const Quat kMount[3] = {Quat::Identity(), Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitX())),
                        Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitY()))};

// 2 and 3 heads over 8 body attitudes each: the fused error is within the reported covariance,
// and the fused roll (about body +Z, head 0's boresight) is far better than head 0 alone.
void CheckFusion(int num_heads) {
  const Rig& rig = TheRig();
  double nees_sum = 0, roll2_fused = 0, roll2_single = 0, sigma_roll_single = 0, sigma_roll_fused = 0;
  const int trials = 8;
  for (int t = 0; t < trials; ++t) {
    const Quat q_body = RandomAttitude(4000 + 10 * num_heads + t);
    std::vector<Identification> ids;
    std::vector<Quat> mounts;
    for (int h = 0; h < num_heads; ++h) {
      ids.push_back(rig.Solve(q_body, kMount[h], 500 + 100 * t + h));
      mounts.push_back(kMount[h]);
      ASSERT_EQ(ids.back().status, SolveStatus::kSolved)
          << "trial " << t << " head " << h << ": " << ids.back().message;
    }
    const MultiHeadSolution mh = SolveMultiHeadChecked(ids, mounts);
    ASSERT_EQ(mh.attitude.status, SolveStatus::kSolved) << mh.message;
    for (int h = 0; h < num_heads; ++h) EXPECT_EQ(mh.head_use[h], HeadUse::kUsed) << "trial " << t << " head " << h;
    const AttitudeSolution& fused = mh.attitude;
    const Vec3 e = BodyError(fused.q_inertial_from_sensor, q_body);
    const double nees = e.dot(fused.covariance_rad2.inverse() * e);
    // chi-square(3): P(> 16.27) = 0.001.
    EXPECT_LT(nees, 16.27) << "trial " << t << ": error " << (e * kRadToArcsec).transpose() << " arcsec";
    nees_sum += nees;
    // Head 0 alone: sensor = body axes (identity mount), so its roll is the body roll.
    const AttitudeSolution one = SolveAttitude(ids[0]);
    const Vec3 e1 = BodyError(one.q_inertial_from_sensor, q_body);
    roll2_fused += e[2] * e[2];
    roll2_single += e1[2] * e1[2];
    sigma_roll_fused += fused.sigma_roll_rad / trials;
    sigma_roll_single += one.sigma_roll_rad / trials;
    // Per trial at least halved (a head with a sparse field constrains body roll less) ...
    EXPECT_LT(fused.sigma_roll_rad, one.sigma_roll_rad / 2) << "trial " << t;
  }
  const double rms_fused = std::sqrt(roll2_fused / trials), rms_single = std::sqrt(roll2_single / trials);
  std::printf("%d heads: mean NEES %.2f, roll sigma %.2f arcsec fused vs %.2f single, RMS roll error %.2f vs %.2f\n",
              num_heads, nees_sum / trials, sigma_roll_fused * kRadToArcsec, sigma_roll_single * kRadToArcsec,
              rms_fused * kRadToArcsec, rms_single * kRadToArcsec);
  // Mean NEES of 8 draws of chi-square(3): 3 +/- 0.87 (1 sd); 99.9% upper bound about 6.
  EXPECT_LT(nees_sum / trials, 6.0);
  // ... and on average far below one head's (measured: about 10 times).
  EXPECT_LT(sigma_roll_fused, sigma_roll_single / 4);
  EXPECT_LT(rms_fused, sigma_roll_single / 3);
  EXPECT_LT(rms_fused, 2 * sigma_roll_fused);
}

TEST(MultiHeadFrames, TwoHeadsFuseWithinCovarianceAndFixRoll) { CheckFusion(2); }
TEST(MultiHeadFrames, ThreeHeadsFuseWithinCovarianceAndFixRoll) { CheckFusion(3); }

// A head that sees no stars (too_few_stars / no_match) is left out and the others' fusion is unchanged.
TEST(MultiHeadFrames, BlindHeadDoesNotSpoilTheFusion) {
  const Rig& rig = TheRig();
  const Quat q_body = RandomAttitude(4100);
  FrameSimOptions blind;
  blind.mag_max = -5;  // no stars: noise, hot pixels and cosmic rays only
  const Identification h0 = rig.Solve(q_body, kMount[0], 601), h1 = rig.Solve(q_body, kMount[1], 602),
                       h2 = rig.Solve(q_body, kMount[2], 603, blind);
  ASSERT_EQ(h0.status, SolveStatus::kSolved);
  ASSERT_EQ(h1.status, SolveStatus::kSolved);
  ASSERT_NE(h2.status, SolveStatus::kSolved) << h2.message;
  const MultiHeadSolution two = SolveMultiHeadChecked({h0, h1}, {kMount[0], kMount[1]});
  const MultiHeadSolution three = SolveMultiHeadChecked({h0, h1, h2}, {kMount[0], kMount[1], kMount[2]});
  ASSERT_EQ(three.attitude.status, SolveStatus::kSolved) << three.message;
  EXPECT_EQ(three.head_use[2], HeadUse::kOwnStatus);  // JSON "use": its own status
  EXPECT_EQ(three.head_use[0], HeadUse::kUsed);
  EXPECT_EQ(three.head_use[1], HeadUse::kUsed);
  EXPECT_THAT(three.attitude.q_inertial_from_sensor, QuaternionNear(two.attitude.q_inertial_from_sensor, 1e-6));
  EXPECT_THAT(three.attitude.q_inertial_from_sensor, QuaternionNear(q_body, 10.0));
  // All heads blind: no solution, never a made-up attitude.
  const MultiHeadSolution none = SolveMultiHeadChecked({h2, h2}, {kMount[0], kMount[2]});
  EXPECT_NE(none.attitude.status, SolveStatus::kSolved);
}

// A head whose frame belongs to another attitude (a wrong solve, or a wrong mount in heads.json)
// solves on its own but disagrees with the two others: it is reported and left out.
TEST(MultiHeadFrames, InconsistentHeadIsLeftOut) {
  const Rig& rig = TheRig();
  const Quat q_body = RandomAttitude(4200);
  const Quat q_other = q_body * Quat(Eigen::AngleAxisd(2 * kDegToRad, Vec3::UnitZ()));
  const Identification h0 = rig.Solve(q_body, kMount[0], 701), h1 = rig.Solve(q_body, kMount[1], 702),
                       h2 = rig.Solve(q_other, kMount[2], 703);
  ASSERT_EQ(h2.status, SolveStatus::kSolved);
  const MultiHeadSolution mh = SolveMultiHeadChecked({h0, h1, h2}, {kMount[0], kMount[1], kMount[2]});
  ASSERT_EQ(mh.attitude.status, SolveStatus::kSolved);
  EXPECT_EQ(mh.head_use[0], HeadUse::kUsed);
  EXPECT_EQ(mh.head_use[1], HeadUse::kUsed);
  EXPECT_EQ(mh.head_use[2], HeadUse::kInconsistent);
  EXPECT_THAT(mh.attitude.q_inertial_from_sensor, QuaternionNear(q_body, 10.0));
  // A mount error well inside the tolerance (20 arcsec) does not split the heads.
  const Quat m2_off = kMount[2] * Quat(Eigen::AngleAxisd(20 * kArcsecToRad, Vec3::UnitX()));
  const Identification h2b = rig.Solve(q_body, m2_off, 704);
  const MultiHeadSolution ok = SolveMultiHeadChecked({h0, h1, h2b}, {kMount[0], kMount[1], kMount[2]});
  EXPECT_EQ(ok.head_use[2], HeadUse::kUsed) << ok.message;
}

TEST(MultiHeadFrames, MismatchedMountCountIsInputError) {
  EXPECT_THROW(SolveMultiHeadChecked({Identification{}, Identification{}}, {Quat::Identity()}), InputError);
  MultiHeadOptions o;
  o.consistency_sigmas = 0;
  EXPECT_THROW(o.Check(), InputError);
}

}  // namespace
}  // namespace ssiu
