#include "inertial/mekf.h"

#include "inertial/propagate.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// Error state after one step of the nonlinear propagation of a perturbed truth, with
// q_true = q_est * exp(dtheta), b_true = b_est + db (the MEKF's error definition).
Vec6 PropagatedError(const Vec6& dx0, const Quat& q, const Vec3& b, const Vec3& w_meas, double dt) {
  const Quat q_true = q * QuatFromRotationVector(dx0.head<3>());
  const Vec3 b_true = b + dx0.tail<3>();
  const Quat q1 = q * QuatFromRotationVector((w_meas - b) * dt);
  const Quat q1_true = q_true * QuatFromRotationVector((w_meas - b_true) * dt);
  Vec6 dx;
  dx.head<3>() = RotationVectorFromQuat(q1.conjugate() * q1_true);
  dx.tail<3>() = dx0.tail<3>();
  return dx;
}

TEST(Mekf, TransitionMatrixMatchesNumericalDerivative) {
  const Quat q = QuatFromRotationVector(Vec3(0.3, -0.2, 1.0));
  const Vec3 b(1e-4, -2e-4, 5e-5);
  for (const Vec3& w_meas : {Vec3(0.02, -0.01, 0.03), Vec3(0.5, 0.8, -0.3), Vec3(1e-9, 0, 0)}) {
    for (double dt : {0.01, 0.5}) {
      const Mat6 f = Mekf::TransitionMatrix(w_meas - b, dt);
      Mat6 num;
      const double h = 1e-6;
      for (int c = 0; c < 6; ++c) {
        Vec6 d = Vec6::Zero();
        d[c] = h;
        num.col(c) = (PropagatedError(d, q, b, w_meas, dt) - PropagatedError(-d, q, b, w_meas, dt)) / (2 * h);
      }
      EXPECT_LT((f - num).cwiseAbs().maxCoeff(), 1e-7) << "w " << w_meas.transpose() << " dt " << dt << "\n"
                                                       << f << "\n\n"
                                                       << num;
    }
  }
}

TEST(Mekf, ProcessNoiseMatchesFineIntegration) {
  // Q = int_0^dt Phi(s) G Qc G' Phi(s)' ds at zero rate, integrated with many small steps.
  MekfNoise n;
  n.rate_white = Mat3::Identity() * 4e-12;
  n.bias_walk = Mat3::Identity() * 9e-16;
  const double dt = 2.0;
  Mat6 p = Mat6::Zero();
  const int steps = 20000;
  const double h = dt / steps;
  for (int i = 0; i < steps; ++i) {
    const Mat6 f = Mekf::TransitionMatrix(Vec3::Zero(), h);
    Mat6 qc = Mat6::Zero();
    qc.block<3, 3>(0, 0) = n.rate_white * h;
    qc.block<3, 3>(3, 3) = n.bias_walk * h;
    p = f * p * f.transpose() + qc;
  }
  const Mat6 q = Mekf::ProcessNoise(n, dt);
  EXPECT_LT(((q - p).cwiseAbs().array() / (q.cwiseAbs().array() + 1e-30)).maxCoeff(), 1e-3) << q << "\n\n" << p;
}

TEST(Mekf, ConvergesToConstantBiasOnSyntheticStaticData) {
  // Static body, gyro bias b, perfect attitude measurements at 1 Hz with 5 arcsec noise.
  const Vec3 bias(2e-5, -1e-5, 3e-5);  // rad/s, about 4, -2, 6 deg/h
  const Quat q_true = QuatFromRotationVector(Vec3(0.1, 0.2, 0.3));
  Mekf f;
  Mat6 p0 = Mat6::Zero();
  p0.block<3, 3>(0, 0) = Mat3::Identity() * std::pow(5 * kArcsecToRad, 2);
  p0.block<3, 3>(3, 3) = Mat3::Identity() * std::pow(1e-4, 2);
  f.Init(q_true, Vec3::Zero(), p0);
  MekfNoise n;
  n.rate_white = Mat3::Identity() * 1e-14;
  n.bias_walk = Mat3::Identity() * 1e-22;
  uint64_t state = 7;
  auto noise = [&] {  // small deterministic pseudo-noise, +-1
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) / 4503599627370496.0 - 1.0;
  };
  for (int s = 1; s <= 600; ++s) {
    for (int k = 0; k < 10; ++k) f.Propagate(bias, 0.1, n);
    const Vec3 v = Vec3(noise(), noise(), noise()) * 5 * kArcsecToRad;
    const Mat3 r = Mat3::Identity() * std::pow(5 * kArcsecToRad / std::sqrt(3.0), 2);
    ASSERT_TRUE(f.UpdateAttitude(q_true * QuatFromRotationVector(v), r, 1e9).accepted);
  }
  EXPECT_LT((f.bias() - bias).norm(), 1e-7);  // 0.02 deg/h
  EXPECT_THAT(f.q(), QuaternionNear(q_true, 5.0));
  EXPECT_LT(std::sqrt(f.P()(3, 3)), 2e-7);
}

TEST(Mekf, GateRejectsOutlierAndLeavesStateUnchanged) {
  Mekf f;
  f.Init(Quat::Identity(), Vec3::Zero(), Mat6::Identity() * 1e-10);
  const Mat3 r = Mat3::Identity() * 1e-10;
  const MekfUpdate u = f.UpdateAttitude(QuatFromRotationVector(Vec3(0.01, 0, 0)), r, 16.0);
  EXPECT_FALSE(u.accepted);
  EXPECT_GT(u.nis, 1e5);
  EXPECT_EQ(f.q().w(), 1.0);
}

}  // namespace
}  // namespace ssiu
