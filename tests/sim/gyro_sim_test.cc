#include "sim/gyro_sim.h"

#include "core/error.h"
#include "inertial/propagate.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

GyroUnit IdealUnit(double rate_hz) {
  GyroUnit u = DefaultFourFogUnit();
  u.rate_hz = rate_hz;
  for (auto& g : u.gyros) {
    g.arw_deg_per_sqrt_h = 0;
    g.bias_instability_dph = 0;
  }
  return u;
}

TEST(GyroSim, IdealGyrosIntegrateToTheTrueAttitudeOnSineMotion) {
  const GyroUnit u = IdealUnit(100);
  MotionProfile p = MotionProfileFromJson(Json{{"type", "sine"}, {"period_s", 20.0}}, "mem");
  GyroSimOptions o;
  o.duration_s = 120;
  const GyroSimulation s = SimulateGyro(u, p, o);
  const RateSolver solver(u.Axes(), u.NoiseArw(), std::vector<bool>(4, true));
  AttitudePropagator prop(s.q0);
  for (size_t k = 0; k < s.t_s.size(); ++k) prop.Step(solver.Solve(s.gyro_dph[k]) * kDegToRad / 3600, 0.01);
  EXPECT_THAT(prop.q(), QuaternionNear(s.q_true.back(), 0.05));
  // Star samples at 1 Hz, noise-free here apart from the configured 5"/30".
  EXPECT_EQ(s.st_t_s.size(), 121u);
}

TEST(GyroSim, StaticBenchSeesEarthRateAndThermalDriftFollowsTheModel) {
  GyroUnit u = IdealUnit(10);
  u.gyros[0].thermal.k_dph[1] = 0.8;  // K10: 0.8 deg/h per (T - 20)/10 C
  u.gyros[0].bias_dph = 1.0;
  MotionProfile p = MotionProfileFromJson(
      Json::parse(R"({"type": "temperature", "latitude_deg": 48.0, "azimuth_deg": 0,
                      "temperature": {"start_c": 20, "segments": [[600, 1.0]]}})"),
      "mem");
  GyroSimOptions o;
  o.duration_s = 900;
  const GyroSimulation s = SimulateGyro(u, p, o);
  const double we = kEarthRateRadS * kRadToDeg * 3600;  // 15.04 deg/h
  const double lat = 48.0 * kDegToRad;
  // Body x north, z up: x sees we cos(lat), z sees we sin(lat); after 600 s at 1 C/min, T = 30 C.
  EXPECT_NEAR(s.gyro_dph.back()[0], we * std::cos(lat) + 1.0 + 0.8, 1e-6);
  EXPECT_NEAR(s.gyro_dph.back()[2], we * std::sin(lat), 1e-6);
  EXPECT_NEAR(s.temp_c.back(), 30.0, 1e-9);
  EXPECT_NEAR(s.body_bias_dph.back().norm(), (u.Axes().transpose() * u.Axes()).inverse().col(0).norm() * 1.8, 1e-9);
}

TEST(GyroSim, NoiseLevelsMatchTheErrorModel) {
  GyroUnit u = DefaultFourFogUnit();
  u.rate_hz = 100;
  for (auto& g : u.gyros) g.bias_instability_dph = 0;
  MotionProfile p;
  p.type = "slew";
  GyroSimOptions o;
  o.duration_s = 200;
  const GyroSimulation s = SimulateGyro(u, p, o);
  // Per-sample white noise: ARW * 60 / sqrt(dt) = 6 deg/h at 100 Hz.
  double sum2 = 0;
  for (size_t k = 0; k < s.t_s.size(); ++k) {
    const double truth = u.axes_body[0].dot(s.w_true_dph[k]);
    sum2 += std::pow(s.gyro_dph[k][0] - truth, 2);
  }
  EXPECT_NEAR(std::sqrt(sum2 / s.t_s.size()), 6.0, 0.15);
}

TEST(GyroSim, FaultAndOutageAreApplied) {
  const GyroUnit u = IdealUnit(10);
  MotionProfile p = MotionProfileFromJson(
      Json::parse(R"({"type": "slew", "faults": [{"gyro": 3, "t_s": 50, "step_dph": 20}],
                      "star_tracker": {"outages_s": [[10.5, 20.5]]}})"),
      "mem");
  GyroSimOptions o;
  o.duration_s = 100;
  const GyroSimulation s = SimulateGyro(u, p, o);
  EXPECT_NEAR(s.gyro_dph.back()[2] - u.axes_body[2].dot(s.w_true_dph.back()), 20.0, 1e-6);
  EXPECT_NEAR(s.gyro_dph[400][2] - u.axes_body[2].dot(s.w_true_dph[400]), 0.0, 1e-6);
  EXPECT_EQ(s.st_t_s.size(), 101u - 10u);
  EXPECT_THROW(MotionProfileFromJson(Json::parse(R"({"type": "wobble"})"), "p.json").Check("p.json", 4), InputError);
}

}  // namespace
}  // namespace ssiu
