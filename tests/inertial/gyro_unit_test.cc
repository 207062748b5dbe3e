#include "inertial/gyro_unit.h"

#include <cstdio>

#include "core/error.h"
#include "inertial/propagate.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(GyroUnit, LeastSquaresRecoversBodyRateAndParityIsBlindToIt) {
  const GyroUnit u = DefaultFourFogUnit();
  const GyroAxes h = u.Axes();
  const std::vector<bool> all(4, true);
  const RateSolver solver(h, u.NoiseArw(), all);
  const Vec3 w(12.5, -300.0, 45.0);
  const GyroVec g = h * w;
  EXPECT_LT((solver.Solve(g) - w).norm(), 1e-9);
  const GyroParity v = ParityMatrix(h, all);
  ASSERT_EQ(v.rows(), 1);
  EXPECT_LT((v * h).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(v.row(0).norm(), 1.0, 1e-12);
  // The textbook parity of 3 orthogonal + 1 skew: (g1 + g2 + g3)/sqrt(6) - g4/sqrt(2).
  EXPECT_NEAR(v(0, 0), 1 / std::sqrt(6.0), 1e-12);
  EXPECT_NEAR(v(0, 3), -1 / std::sqrt(2.0), 1e-12);
  EXPECT_LT(std::abs((v * g)(0)), 1e-9);
  // Body-rate covariance of the redundant unit: (H'H)^-1 * arw^2, smaller than a triad's.
  EXPECT_NEAR(solver.Cov()(0, 0), 5.0 / 6.0 * 1e-4, 1e-12);
}

TEST(GyroUnit, DroppingAGyroStillSolvesAndFiveGyrosHaveTwoParityRelations) {
  GyroUnit u = DefaultFourFogUnit();
  const Vec3 w(1, 2, 3);
  std::vector<bool> use = {true, false, true, true};
  const RateSolver s(u.Axes(), u.NoiseArw(), use);
  GyroVec g = u.Axes() * w;
  g[1] = 1e6;  // the dropped gyro's output must not matter
  EXPECT_LT((s.Solve(g) - w).norm(), 1e-9);
  EXPECT_EQ(ParityMatrix(u.Axes(), use).rows(), 0);
  EXPECT_THROW(RateSolver(u.Axes(), u.NoiseArw(), {true, true, false, false}), InputError);

  u.axes_body.push_back(Vec3(1, -1, 0).normalized());
  u.gyros.push_back(GyroErrorModel{});
  const GyroParity v = ParityMatrix(u.Axes(), std::vector<bool>(5, true));
  ASSERT_EQ(v.rows(), 2);
  EXPECT_LT((v * u.Axes()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((v * v.transpose() - Eigen::Matrix2d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
}

// Parity rows on a subset whose axes span only a plane (two pairs of parallel gyros of a six-gyro unit):
// its left null space has two dimensions, one row is asked for, and it must still be blind to every
// rate, of unit length and zero on the gyros left out.
TEST(GyroUnit, ParityOfARankDeficientSubsetIsStillBlindToTheRate) {
  GyroUnit u = DefaultFourFogUnit();
  u.axes_body = {Vec3::UnitX(), Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitY(), Vec3::UnitZ(), Vec3(1, 1, 1).normalized()};
  u.gyros.assign(6, GyroErrorModel{});
  const std::vector<bool> use = {true, true, true, true, false, false};
  const GyroParity v = ParityMatrix(u.Axes(), use);
  ASSERT_EQ(v.rows(), 1);
  EXPECT_LT((v * u.Axes()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(v.row(0).norm(), 1.0, 1e-12);
  EXPECT_EQ(v(0, 4), 0.0);
  EXPECT_EQ(v(0, 5), 0.0);
}

// The unit's axes must span three dimensions: refused when the smallest singular value of H is below 1e-3.
// Rows (a, b, c), (a, -b, -c), (-a, b, -c), (-a, -b, c) with a^2 + b^2 + c^2 = 1 are unit axes whose
// columns are orthogonal, so H's singular values are the columns' norms 2a, 2b, 2c: c = 5e-4 is the bound.
TEST(GyroUnit, AxesNearlyInAPlaneAreRefused) {
  for (double c : {0.0, 1e-4, 4e-4, 6e-4, 1e-2, 0.5}) {
    const double a = std::sqrt((1 - c * c) * 0.6), b = std::sqrt((1 - c * c) * 0.4);
    GyroUnit u = DefaultFourFogUnit();
    u.axes_body = {Vec3(a, b, c), Vec3(a, -b, -c), Vec3(-a, b, -c), Vec3(-a, -b, c)};
    if (2 * c < 1e-3) {
      try {
        u.Check("unit.json");
        ADD_FAILURE() << "c " << c << ": smallest singular value " << 2 * c << " accepted";
      } catch (const InputError& e) {
        EXPECT_THAT(e.what(), ::testing::HasSubstr("do not span three dimensions")) << c;
      }
    } else {
      EXPECT_NO_THROW(u.Check("unit.json")) << "c " << c << ": smallest singular value " << 2 * c;
    }
  }
}

TEST(GyroUnit, JsonRoundTripAndDefaults) {
  GyroUnit u = DefaultFourFogUnit();
  u.gyros[2].bias_dph = 3.5;
  u.gyros[1].thermal.k_dph[4] = 0.7;
  u.gyros[0].magnetic.along_dph_per_ut = 0.01;
  const GyroUnit back = GyroUnitFromJson(GyroUnitToJson(u), "mem");
  ASSERT_EQ(back.size(), 4);
  EXPECT_EQ(back.gyros[2].bias_dph, 3.5);
  EXPECT_EQ(back.gyros[1].thermal.k_dph[4], 0.7);
  EXPECT_EQ(back.gyros[0].magnetic.along_dph_per_ut, 0.01);
  EXPECT_LT((back.axes_body[3] - Vec3(1, 1, 1).normalized()).norm(), 1e-12);
  EXPECT_FALSE(back.calibrated);
  // A bench-calibrated unit keeps its flag and its asymmetry.
  u.calibrated = true;
  u.gyros[3].scale_factor_asymmetry_ppm = -45;
  const GyroUnit cal = GyroUnitFromJson(GyroUnitToJson(u), "mem");
  EXPECT_TRUE(cal.calibrated);
  EXPECT_EQ(cal.gyros[3].scale_factor_asymmetry_ppm, -45);
  // A "default" block applies to every gyro; per-gyro fields override it.
  const Json j = Json::parse(R"({"default": {"arw_deg_per_sqrt_h": 0.02}, "gyros": [
      {"axis": [1,0,0]}, {"axis": [0,2,0], "arw_deg_per_sqrt_h": 0.03}, {"axis": [0,0,1]}]})");
  const GyroUnit t = GyroUnitFromJson(j, "mem");
  EXPECT_EQ(t.gyros[0].arw_deg_per_sqrt_h, 0.02);
  EXPECT_EQ(t.gyros[1].arw_deg_per_sqrt_h, 0.03);
  EXPECT_NEAR(t.axes_body[1].y(), 1.0, 1e-12);
}

TEST(GyroUnit, BadUnitsAreInputErrorsNamingTheField) {
  auto msg = [](const char* text) {
    try {
      GyroUnitFromJson(Json::parse(text), "unit.json");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_THAT(msg(R"({"gyros": [{"axis": [1,0,0]}, {"axis": [0,1,0]}]})"), ::testing::HasSubstr("need 3 to 6"));
  EXPECT_THAT(msg(R"({"gyros": [{"axis": [1,0,0]}, {"axis": [0,1,0]}, {"axis": [1,1,0]}]})"),
              ::testing::HasSubstr("span"));
  EXPECT_THAT(msg(R"({"gyros": [{"axis": [1,0,0]}, {"axis": [0,1,0]}, {"axis": [0,0,1], "arw_deg_per_sqrt_h": -1}]})"),
              ::testing::HasSubstr("arw_deg_per_sqrt_h"));
  EXPECT_THAT(msg(R"({"gyros": [{"axis": [1,0]}]})"), ::testing::HasSubstr("axis"));
  EXPECT_THAT(msg(R"({"rate": 1})"), ::testing::HasSubstr("gyros"));
}

TEST(Propagate, ConingCorrectionBeatsPlainIntegrationOnConingMotion) {
  // Classical coning: w(t) = (-a W sin Wt... ) has a closed-form attitude
  // q(t) = exp(beta/2 (cos Wt, sin Wt, 0) ...). Use the form q(t) = qz(Wt) * qx(a) * qz(-Wt)
  // (body spins at -W about its z while its z axis precesses at W): w_body from q^-1 dq/dt.
  const double a = 0.05, wc = 2 * kPi * 2.0;  // 0.05 rad cone at 2 Hz
  auto q_at = [&](double t) {
    return Quat(Eigen::AngleAxisd(wc * t, Vec3::UnitZ()) * Eigen::AngleAxisd(a, Vec3::UnitX()) *
                Eigen::AngleAxisd(-wc * t, Vec3::UnitZ()));
  };
  auto w_at = [&](double t) {
    const double e = 1e-6;
    const Quat dq = q_at(t - e).conjugate() * q_at(t + e);
    return Vec3(RotationVectorFromQuat(dq) / (2 * e));
  };
  const double dt = 0.01, t_end = 10.0;
  AttitudePropagator with(q_at(0));
  Quat without = q_at(0);
  for (int k = 1; k * dt <= t_end + 1e-9; ++k) {
    // Mean rate over the step by Simpson's rule (what an FOG outputs).
    const double t0 = (k - 1) * dt, t1 = k * dt;
    const Vec3 w = (w_at(t0) + 4 * w_at(0.5 * (t0 + t1)) + w_at(t1)) / 6.0;
    with.Step(w, dt);
    without = (without * QuatFromRotationVector(w * dt)).normalized();
  }
  const double err_with = AttitudeErrorRad(with.q(), q_at(t_end)) * kRadToArcsec;
  const double err_without = AttitudeErrorRad(without, q_at(t_end)) * kRadToArcsec;
  EXPECT_LT(err_with, 0.2 * err_without) << err_with << " vs " << err_without;
  std::printf("coning: %.3f arcsec with correction, %.3f without\n", err_with, err_without);
  EXPECT_LT(err_with, 5.0);
}

TEST(Propagate, ExpLogRoundTripAndConstantRateIsExact) {
  const Vec3 phi(0.3, -1.2, 2.0);
  EXPECT_LT((RotationVectorFromQuat(QuatFromRotationVector(phi)) - phi).norm(), 1e-12);
  EXPECT_LT((RotationVectorFromQuat(QuatFromRotationVector(Vec3(1e-9, 0, 0))) - Vec3(1e-9, 0, 0)).norm(), 1e-20);
  const Vec3 w(0.01, 0.02, -0.03);
  AttitudePropagator p(Quat::Identity());
  for (int k = 0; k < 1000; ++k) p.Step(w, 0.01);
  EXPECT_THAT(p.q(), QuaternionNear(QuatFromRotationVector(w * 10.0), 1e-6));
  // Bortz to second order for a linear rate equals the two-sample coning form.
  const Vec3 w0(0.1, 0.0, 0.2), w1(0.0, 0.3, 0.1);
  EXPECT_LT((RotationVectorLinearRate(w0, w1, 0.1) - Vec3(0.5 * 0.1 * (w0 + w1) + 0.01 / 12 * w0.cross(w1))).norm(),
            1e-15);
}

}  // namespace
}  // namespace ssiu
