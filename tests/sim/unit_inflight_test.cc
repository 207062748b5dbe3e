// `ssiu fuse --calibrate-unit` (inertial/unit_inflight.h): two simulated slewing missions (seeds 71-72;
// the long test uses 1-20), and the flag end to end.
#include <filesystem>
#include <fstream>

#include "sim/unit_inflight_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(UnitInflight, ScaleFactorsAndAxesWithinThreeSigmaAndOutageErrorShrinks) {
  testing::InflightScore s;
  for (uint64_t seed : {71u, 72u}) testing::RunInflightCase(seed, &s);
  ASSERT_EQ(s.cases, 2) << s.Describe();
  EXPECT_GE(s.within_3sigma, s.parameters - 1) << s.Describe();  // at most one of 24 outside 3 sigma
  EXPECT_LT(s.MeanNees(), 3 + 3 * std::sqrt(6.0 / 8)) << s.Describe();
  EXPECT_GT(std::sqrt(s.nominal2), 3 * std::sqrt(s.calibrated2)) << s.Describe();
  // The processor's recursive estimator over the same logs (FuseOptions::calibrate_unit).
  EXPECT_EQ(s.online_applied, 2) << s.Describe();
  ASSERT_EQ(s.online_parameters, 24) << s.Describe();
  EXPECT_GE(s.online_within_3sigma, s.online_parameters - 1) << s.Describe();
  EXPECT_GT(std::sqrt(s.online_nominal2), 3 * std::sqrt(s.online_calibrated2)) << s.Describe();
}

// Without noise the linearised model must give the simulator's errors back to their second-order
// residue (the check of the hand-derived regressors against the simulator's own integration).
TEST(UnitInflight, NoiselessMissionGivesTheErrorsBack) {
  GyroUnit nominal = DefaultFourFogUnit();
  nominal.rate_hz = 10;
  for (auto& g : nominal.gyros) g.arw_deg_per_sqrt_h = 1e-5, g.bias_instability_dph = 0;
  GyroUnit truth = nominal;
  const double sf[4] = {250, -120, 60, 300}, mu[4] = {180, -240, 90, 30}, nu[4] = {-60, 150, -270, 120};
  for (int i = 0; i < 4; ++i) {
    truth.gyros[i].scale_factor_ppm = sf[i];
    truth.gyros[i].misalignment_arcsec[0] = mu[i], truth.gyros[i].misalignment_arcsec[1] = nu[i];
    truth.gyros[i].bias_dph = 0.5 * (i + 1);
  }
  MotionProfile p;
  p.type = "sine";
  p.amplitude_dps = Vec3(1, 1, 1);
  p.periods_s = Vec3(300, 420, 540);
  p.st_sigma_cross_arcsec = p.st_sigma_roll_arcsec = 0;
  GyroSimOptions so;
  so.duration_s = 1800;
  const GyroSimulation sim = SimulateGyro(truth, p, so);
  GyroLog log;
  log.t_s = sim.t_s, log.rates_dph = sim.gyro_dph;
  StarTrackerLog st;
  st.t_s = sim.st_t_s, st.q_inertial_from_body = sim.st_q;
  const InflightCalResult c = CalibrateUnitInFlight(log, st, nominal, 0.01, 0.01, InflightCalOptions{});
  ASSERT_TRUE(c.ok) << c.message;
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(c.gyros[i].scale_factor_ppm, sf[i], 0.2) << i;
    EXPECT_NEAR(c.gyros[i].misalignment_arcsec[0], mu[i], 0.3) << i;
    EXPECT_NEAR(c.gyros[i].misalignment_arcsec[1], nu[i], 0.3) << i;
  }
  // On top of a bench calibration that left 20 ppm and 40 arcsec: the calibrated unit is the truth.
  GyroUnit bench = truth;
  bench.calibrated = true;
  for (int i = 0; i < 4; ++i) {
    bench.gyros[i].scale_factor_ppm -= 20;
    bench.gyros[i].misalignment_arcsec[0] -= 40;
  }
  const InflightCalResult cb = CalibrateUnitInFlight(log, st, bench, 0.01, 0.01, InflightCalOptions{});
  ASSERT_TRUE(cb.ok) << cb.message;
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(cb.unit.gyros[i].scale_factor_ppm, sf[i], 0.2) << i;
    const Vec3 a = cb.unit.SensingAxis(i), t = truth.SensingAxis(i);
    EXPECT_LT(std::atan2(a.cross(t).norm(), a.dot(t)) * kRadToArcsec, 0.3) << i;
    EXPECT_NEAR(cb.gyros[i].scale_factor_ppm, 1e6 * ((1 + 1e-6 * sf[i]) / (1 + 1e-6 * (sf[i] - 20)) - 1), 0.2) << i;
  }
}

TEST(UnitInflight, FuseFlagWritesTheCalibrationAndRefusesBodyRates) {
  const std::string d = testing::TempDir("fuse_calibrate_unit");
  std::ofstream(d + "/prof.json") << R"({"type": "sine", "amplitude_dps": [1, 1, 1], "periods_s": [300, 420, 540]})";
  std::ofstream(d + "/unit.json") << R"({"rate_hz": 10, "gyros": [
    {"axis": [1,0,0], "scale_factor_ppm": 200, "misalignment_arcsec": [120, -60]},
    {"axis": [0,1,0]}, {"axis": [0,0,1]}, {"axis": [1,1,1]}]})";
  std::ofstream(d + "/nominal.json") << R"({"rate_hz": 10, "gyros": [
    {"axis": [1,0,0]}, {"axis": [0,1,0]}, {"axis": [0,0,1]}, {"axis": [1,1,1]}]})";
  testing::SsiuResult r = testing::RunSsiu("simulate gyro --unit " + d + "/unit.json --profile " + d +
                                           "/prof.json --duration-s 1800 --seed 4 --out " + d + "/sim");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string fuse = "fuse --gyro " + d + "/sim/gyro.csv --st " + d + "/sim/st.csv --unit " + d +
                           "/nominal.json --json " + d + "/f.json";
  r = testing::RunSsiu(fuse);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_FALSE(ReadJsonFile(d + "/f.json").contains("unit_calibration"));  // off by default
  r = testing::RunSsiu(fuse + " --calibrate-unit");
  ASSERT_EQ(r.status, 0) << r.output;
  const Json c = ReadJsonFile(d + "/f.json").at("unit_calibration");
  EXPECT_EQ(c.at("status"), "fitted");
  const Json& g1 = c.at("gyros")[0];
  EXPECT_NEAR(g1.at("scale_factor_ppm").get<double>(), 200, 4 * g1.at("scale_factor_sigma_ppm").get<double>());
  EXPECT_NEAR(g1.at("misalignment_arcsec")[0].get<double>(), 120,
              4 * g1.at("misalignment_sigma_arcsec")[0].get<double>());
  EXPECT_TRUE(c.at("unit").at("calibrated").get<bool>());
  // A body-rate log has no gyro outputs to calibrate: one line, exit 1.
  std::ofstream(d + "/body.csv") << "t_s,wx_dph,wy_dph,wz_dph\n0.1,0,0,0\n0.2,0,0,0\n0.3,0,0,0\n";
  r = testing::RunSsiu("fuse --gyro " + d + "/body.csv --st " + d + "/sim/st.csv --calibrate-unit");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("g1_dph"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace ssiu
