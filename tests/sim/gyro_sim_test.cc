#include "sim/gyro_sim.h"

#include <cmath>

#include "core/error.h"
#include "inertial/propagate.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

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
  MotionProfile p = MotionProfileFromJson(Json::parse(R"({"type": "temperature", "latitude_deg": 48.0, "azimuth_deg": 0,
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

// The bench profile's reference: a static position sees the Earth's rate only (15.04 deg/h, its
// vertical part sin(lat) along the up axis), a table rate adds itself along the up axis; gyro.csv's
// ideal outputs are the reference along each axis.
TEST(GyroSim, BenchProfileReferenceIsEarthPlusTableRate) {
  MotionProfile p = BenchCampaignProfile();
  p.bench = {{100, -Vec3::UnitY(), 30, 0}, {100, Vec3(1, 1, 0), 0, -10}};
  GyroSimOptions so;
  so.duration_s = BenchDurationS(p);
  const GyroUnit unit = IdealUnit(10);
  const GyroSimulation sim = SimulateGyro(unit, p, so);
  ASSERT_TRUE(sim.bench_reference);
  const double earth_dph = kEarthRateRadS * kRadSToDph, lat = p.latitude_deg * kDegToRad;
  for (size_t k = 0; k < sim.t_s.size(); k += 97) {
    const Vec3& w = sim.w_mean_dph[k];
    const bool table = sim.t_s[k] > 100;
    const Vec3 up = table ? Vec3(1, 1, 0).normalized() : -Vec3::UnitY();
    if (!table) {
      EXPECT_NEAR(w.norm(), earth_dph, 1e-9) << k;
    }
    EXPECT_NEAR(w.dot(up), earth_dph * std::sin(lat) + (table ? -36000.0 : 0.0), 1e-6) << k;
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(sim.gyro_dph[k][i], unit.axes_body[i].dot(w), 1e-6) << k;
  }
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
  MotionProfile p =
      MotionProfileFromJson(Json::parse(R"({"type": "slew", "faults": [{"gyro": 3, "t_s": 50, "step_dph": 20}],
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

// Every fault shape on its own gyro, in sequence: a step that ends, a ramp given per second, a noise
// burst and a stuck output; the output error against the true rate shows each one.
TEST(GyroSim, FaultShapesStepRampNoiseBurstAndStuck) {
  const GyroUnit u = IdealUnit(10);
  MotionProfile p = MotionProfileFromJson(Json::parse(R"({"type": "sine", "period_s": 40, "faults": [
      {"gyro": 1, "t_s": 10, "end_s": 20, "step_dph": 30},
      {"gyro": 2, "t_s": 20, "ramp_dph_per_s": 5},
      {"gyro": 3, "t_s": 30, "end_s": 60, "noise_dph": 50},
      {"gyro": 4, "t_s": 40, "stuck": true}]})"),
                                          "mem");
  p.Check("mem", 4);
  GyroSimOptions o;
  o.duration_s = 100;
  const GyroSimulation s = SimulateGyro(u, p, o);
  MotionProfile clean_profile = p;
  clean_profile.faults.clear();
  const GyroSimulation clean = SimulateGyro(u, clean_profile, o);  // ideal gyros: the mean true rate
  auto err = [&](size_t k, int i) { return s.gyro_dph[k][i] - clean.gyro_dph[k][i]; };
  auto k_at = [&](double t) { return static_cast<size_t>(std::lround(t * 10)) - 1; };  // sample ending at t
  // Step on gyro 1 over (10, 20].
  EXPECT_NEAR(err(k_at(10), 0), 0.0, 1e-6);
  EXPECT_NEAR(err(k_at(15), 0), 30.0, 1e-6);
  EXPECT_NEAR(err(k_at(20), 0), 30.0, 1e-6);
  EXPECT_NEAR(err(k_at(20.1), 0), 0.0, 1e-6);
  // Ramp of 5 deg/h per second on gyro 2 (the sample's end time sets the ramp).
  EXPECT_NEAR(err(k_at(30), 1), 50.0, 1e-6);
  EXPECT_NEAR(err(k_at(90), 1), 350.0, 1e-6);
  // Noise burst on gyro 3: the ideal gyro's error is the burst, 50 deg/h RMS, and nothing after it.
  double sum2 = 0;
  for (double t = 30.1; t <= 60.0 + 1e-9; t += 0.1) sum2 += err(k_at(t), 2) * err(k_at(t), 2);
  EXPECT_NEAR(std::sqrt(sum2 / 300), 50.0, 6.0);
  EXPECT_NEAR(err(k_at(70), 2), 0.0, 1e-6);
  // Stuck gyro 4 keeps its last output while the sine rate moves on.
  for (double t = 40.1; t <= 100; t += 7.3) EXPECT_EQ(s.gyro_dph[k_at(t)][3], s.gyro_dph[k_at(40)][3]);
  EXPECT_GT(std::abs(err(k_at(50), 3)), 100.0);
  // The profile round-trips through JSON and bad faults are refused naming the file.
  const MotionProfile back = MotionProfileFromJson(Json{{"faults", {p.faults[2].ToJson(), p.faults[3].ToJson()}}}, "m");
  EXPECT_EQ(back.faults[0].end_s, 60.0);
  EXPECT_EQ(back.faults[0].noise_dph, 50.0);
  EXPECT_TRUE(back.faults[1].stuck);
  EXPECT_TRUE(std::isinf(back.faults[1].end_s));
  auto bad = [](const char* text) {
    try {
      MotionProfileFromJson(Json::parse(text), "p.json").Check("p.json", 4);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_THAT(bad(R"({"faults": [{"gyro": 1, "t_s": 5, "end_s": 4, "step_dph": 1}]})"), HasSubstr("end_s"));
  EXPECT_THAT(bad(R"({"faults": [{"gyro": 1, "t_s": 5, "noise_dph": -1}]})"), HasSubstr("noise_dph"));
  EXPECT_THAT(bad(R"({"faults": [{"gyro": 1, "t_s": 5, "stuck": 1}]})"), HasSubstr("stuck"));
  EXPECT_THAT(bad(R"({"faults": [{"gyro": 1, "t_s": 5, "ramp_dph_per_h": 1, "ramp_dph_per_s": 1}]})"),
              HasSubstr("not both"));
}

}  // namespace
}  // namespace ssiu
