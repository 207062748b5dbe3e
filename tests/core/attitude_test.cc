#include "core/attitude.h"

#include <cmath>

#include "core/error.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(Attitude, BoresightPointsAtRaDec) {
  const double ra = 1.1, dec = -0.4;
  const Quat q = QuatFromRaDecRoll(ra, dec, 0.3);
  EXPECT_LT((q * Vec3::UnitZ() - UnitFromRaDec(ra, dec)).norm(), 1e-12);
}

TEST(Attitude, RollZeroPutsImageUpOnNorthAndRightOnWest) {
  const double ra = 0.0, dec = 0.0;
  const Quat q = QuatFromRaDecRoll(ra, dec, 0.0);
  // At ra = dec = 0: north is +Z inertial, east is +Y inertial.
  EXPECT_LT((q * Vec3(0, -1, 0) - Vec3::UnitZ()).norm(), 1e-12);  // image up -> north
  EXPECT_LT((q * Vec3(1, 0, 0) - Vec3(0, -1, 0)).norm(), 1e-12);  // image right -> west
}

TEST(Attitude, RollIsRightHandedAboutBoresight) {
  const Quat q0 = QuatFromRaDecRoll(0.5, 0.2, 0.0);
  const Quat q1 = QuatFromRaDecRoll(0.5, 0.2, 0.25);
  const Quat expect = q0 * Quat(Eigen::AngleAxisd(0.25, Vec3::UnitZ()));
  EXPECT_THAT(q1, QuaternionNear(expect, 1e-6));
}

TEST(Attitude, RaDecRollRoundTrip) {
  for (double ra : {0.1, 2.0, 4.5, 6.2}) {
    for (double dec : {-1.4, -0.3, 0.0, 0.9, 1.5}) {
      for (double roll : {0.0, 1.0, 3.5, 6.0}) {
        const RaDecRoll r = RaDecRollFromQuat(QuatFromRaDecRoll(ra, dec, roll));
        EXPECT_NEAR(r.ra_rad, ra, 1e-9);
        EXPECT_NEAR(r.dec_rad, dec, 1e-9);
        EXPECT_NEAR(std::remainder(r.roll_rad - roll, 2 * kPi), 0.0, 1e-9);
      }
    }
  }
}

TEST(Attitude, WxyzHasNonNegativeScalar) {
  const Quat q(-0.5, 0.5, -0.5, 0.5);
  const auto w = ToWxyz(q);
  EXPECT_GE(w[0], 0.0);
  EXPECT_NEAR(w[0], 0.5, 1e-12);
  EXPECT_NEAR(w[1], -0.5, 1e-12);
  EXPECT_THROW(FromWxyz(0, 0, 0, 0), InputError);
  EXPECT_THROW(FromWxyz(NAN, 0, 0, 1), InputError);
}

TEST(Attitude, ErrorSplitSeparatesCrossAndRoll) {
  const Quat q_true = QuatFromRaDecRoll(1.0, 0.5, 0.2);
  const double roll = 30 * kArcsecToRad, tilt = 10 * kArcsecToRad;
  const Quat q_roll = q_true * Quat(Eigen::AngleAxisd(roll, Vec3::UnitZ()));
  auto s = SplitAttitudeError(q_roll, q_true);
  EXPECT_NEAR(s.roll_rad, roll, 1e-10);
  EXPECT_NEAR(s.cross_rad, 0.0, 1e-10);
  const Quat q_tilt = q_true * Quat(Eigen::AngleAxisd(tilt, Vec3::UnitX()));
  s = SplitAttitudeError(q_tilt, q_true);
  EXPECT_NEAR(s.cross_rad, tilt, 1e-10);
  EXPECT_NEAR(s.roll_rad, 0.0, 1e-10);
  EXPECT_NEAR(s.total_rad, tilt, 1e-10);
}

TEST(Attitude, UniformQuaternionsCoverTheSphere) {
  // The boresights of uniform rotations are uniform on the sphere: mean z near 0, mean z^2 near 1/3.
  double sz = 0, sz2 = 0;
  const int n = 20000;
  uint64_t s = 12345;
  auto next = [&s]() {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(s >> 11) / 9007199254740992.0;
  };
  for (int i = 0; i < n; ++i) {
    const Vec3 z = QuatFromUniform(next(), next(), next()) * Vec3::UnitZ();
    sz += z.z();
    sz2 += z.z() * z.z();
  }
  EXPECT_NEAR(sz / n, 0.0, 0.02);
  EXPECT_NEAR(sz2 / n, 1.0 / 3.0, 0.01);
}

}  // namespace
}  // namespace ssiu
