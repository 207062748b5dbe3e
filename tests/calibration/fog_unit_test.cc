// The unit bench calibration (`ssiu fog unit-calibrate`): simulated campaigns scored against the
// simulator's truth, the calibrated unit in the processor, and the command end to end.
#include "calibration/fog_unit.h"

#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "fog_unit_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// Seeds 201-202 (the long test uses 1-20); 10 Hz keeps each campaign under a second.
TEST(FogUnit, CampaignParametersWithinThreeSigma) {
  UnitCalScore s;
  for (uint64_t seed : {201u, 202u}) ScoreUnitCampaign(MakeUnitCampaign(seed, 10), &s);
  EXPECT_GE(s.Fraction(), 0.95) << s.Describe();
  // 8 gyros: the mean NEES of 4 dof has a standard deviation of sqrt(8/8) = 1.
  EXPECT_GT(s.MeanNees(), 1.0) << s.Describe();
  EXPECT_LT(s.MeanNees(), 8.0) << s.Describe();
}

TEST(FogUnit, SelectsAsymmetryAndNonlinearityOnlyWhenPresent) {
  GyroUnit truth = DefaultFourFogUnit();
  truth.rate_hz = 10;
  GyroUnit nominal = truth;
  truth.gyros[0].scale_factor_asymmetry_ppm = 60;
  truth.gyros[1].scale_factor_nonlinearity_ppm_per_dps = 2;
  GyroSimOptions so;
  so.seed = 7;
  const MotionProfile bench = BenchCampaignProfile();
  so.duration_s = BenchDurationS(bench);
  const GyroSimulation sim = SimulateGyro(truth, bench, so);
  UnitBenchLog log;
  log.t_s = sim.t_s, log.temp_c = sim.temp_c, log.ref_dph = sim.w_mean_dph;
  log.g_dph.assign(4, {});
  for (const auto& g : sim.gyro_dph) {
    for (int i = 0; i < 4; ++i) log.g_dph[i].push_back(g[i]);
  }
  const UnitCalibrationResult r = CalibrateUnit({log}, nominal, UnitCalibrationOptions{});
  EXPECT_NEAR(r.gyros[0].scale_factor_asymmetry_ppm, 60, 3);
  EXPECT_EQ(r.gyros[0].scale_factor_nonlinearity_ppm_per_dps, 0);
  EXPECT_NEAR(r.gyros[1].scale_factor_nonlinearity_ppm_per_dps, 2, 0.3);
  EXPECT_EQ(r.gyros[1].scale_factor_asymmetry_ppm, 0);
  EXPECT_EQ(r.gyros[2].scale_factor_asymmetry_ppm, 0);
  EXPECT_EQ(r.gyros[2].scale_factor_nonlinearity_ppm_per_dps, 0);
  EXPECT_TRUE(r.unit.calibrated);
}

// The processor's inverse of the simulator's output model: a calibrated unit's outputs of a known
// rate give back the rate along each sensing axis.
TEST(FogUnit, RemoveCalibratedErrorsInvertsTheOutputModel) {
  GyroUnit u = DefaultFourFogUnit();
  u.calibrated = true;
  for (int i = 0; i < 4; ++i) {
    u.gyros[i].bias_dph = 0.5 * (i + 1);
    u.gyros[i].scale_factor_ppm = 100.0 * (i - 1.5);
    u.gyros[i].scale_factor_asymmetry_ppm = 30.0 * (i % 2 ? 1 : -1);
    u.gyros[i].scale_factor_nonlinearity_ppm_per_dps = 1.5;
  }
  for (double sign : {1.0, -1.0}) {
    const Vec3 w = sign * Vec3(20, -5, 12) * 3600;  // deg/h
    GyroVec g(4);
    for (int i = 0; i < 4; ++i) {
      const auto& e = u.gyros[i];
      const double wa = u.SensingAxis(i).dot(w);
      const double s = wa > 0 ? 1 : -1;
      g[i] = (1 + 1e-6 * (e.scale_factor_ppm + e.scale_factor_asymmetry_ppm * s +
                          e.scale_factor_nonlinearity_ppm_per_dps * std::abs(wa) / 3600)) *
                 wa +
             e.bias_dph;
    }
    u.RemoveCalibratedErrors(&g);
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(g[i], u.SensingAxis(i).dot(w), 1e-3) << i;
  }
  u.calibrated = false;  // a unit that is not calibrated is left alone
  GyroVec g = GyroVec::Constant(4, 7.0);
  u.RemoveCalibratedErrors(&g);
  EXPECT_EQ(g, GyroVec::Constant(4, 7.0));
}

// The attitude error through a 5-minute outage in a 1 deg/s slew: the issue asks for 5x; the RMS
// over two seeds is compared (one realisation's ARW can make a single ratio noisy).
TEST(FogUnit, CalibratedUnitShrinksSlewOutageError) {
  double nominal2 = 0, calibrated2 = 0;
  for (uint64_t seed : {204u, 205u}) {
    const UnitCampaign c = MakeUnitCampaign(seed, 10);
    const double nominal = OutageErrorArcsec(c.truth, c.nominal, seed, SlewAxisForSeed(seed));
    const double calibrated = OutageErrorArcsec(c.truth, c.fit.unit, seed, SlewAxisForSeed(seed));
    nominal2 += nominal * nominal, calibrated2 += calibrated * calibrated;
  }
  EXPECT_GT(std::sqrt(nominal2), 5 * std::sqrt(calibrated2))
      << "RMS nominal " << std::sqrt(nominal2 / 2) << " arcsec, calibrated " << std::sqrt(calibrated2 / 2);
}

TEST(FogUnit, TooShortOrDegenerateCampaignIsInputError) {
  GyroUnit unit = DefaultFourFogUnit();
  unit.rate_hz = 10;
  UnitBenchLog log;
  log.file = "flat.csv";
  log.g_dph.assign(4, {});
  for (int k = 1; k <= 6000; ++k) {  // 600 s about body z only: the axes' x, y parts are not observable
    log.t_s.push_back(0.1 * k);
    log.ref_dph.emplace_back(0, 0, 36000);
    for (int i = 0; i < 4; ++i) log.g_dph[i].push_back(unit.axes_body[i].z() * 36000);
  }
  EXPECT_THROW(CalibrateUnit({log}, unit, UnitCalibrationOptions{}), InputError);
  log.t_s.resize(50), log.ref_dph.resize(50);
  for (auto& g : log.g_dph) g.resize(50);
  EXPECT_THROW(CalibrateUnit({log}, unit, UnitCalibrationOptions{}), InputError);
}

class FogUnitCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(testing::SsiuProgram())) GTEST_SKIP() << "the ssiu program is not built";
    dir_ = testing::TempDir("fog_unit");
  }
  int Ssiu(const std::string& args, std::string* out) { return testing::Run(testing::SsiuProgram() + " " + args, out); }
  std::string dir_;
};

TEST_F(FogUnitCli, SimulateCalibrateFuse) {
  std::ofstream(dir_ + "/truth.json") << R"({"rate_hz": 10, "gyros": [
    {"axis": [1,0,0], "bias_dph": 1.0, "scale_factor_ppm": 120, "misalignment_arcsec": [90, -60]},
    {"axis": [0,1,0], "bias_dph": -2.0, "scale_factor_ppm": -200, "misalignment_arcsec": [-150, 40]},
    {"axis": [0,0,1], "bias_dph": 0.5, "scale_factor_ppm": 40, "misalignment_arcsec": [30, 200]},
    {"axis": [1,1,1], "bias_dph": 1.5, "scale_factor_ppm": 260, "misalignment_arcsec": [-240, -100]}]})";
  std::ofstream(dir_ + "/nominal.json") << R"({"rate_hz": 10, "gyros": [
    {"axis": [1,0,0]}, {"axis": [0,1,0]}, {"axis": [0,0,1]}, {"axis": [1,1,1]}]})";
  std::string out;
  ASSERT_EQ(
      Ssiu("simulate gyro --unit " + dir_ + "/truth.json --profile bench --seed 5 --out " + dir_ + "/bench", &out), 0)
      << out;
  ASSERT_EQ(Ssiu("fog unit-calibrate " + dir_ + "/bench/gyro.csv --unit " + dir_ + "/nominal.json --out " + dir_ +
                     "/unit.json --json " + dir_ + "/report.json",
                 &out),
            0)
      << out;
  const GyroUnit cal = LoadGyroUnit(dir_ + "/unit.json");
  EXPECT_TRUE(cal.calibrated);
  const Json rep = ReadJsonFile(dir_ + "/report.json");
  ASSERT_EQ(rep.at("gyros").size(), 4u);
  const Json& g2 = rep.at("gyros")[1];
  EXPECT_NEAR(g2.at("scale_factor_ppm").get<double>(), -200, 4 * g2.at("scale_factor_sigma_ppm").get<double>());
  EXPECT_NEAR(cal.gyros[1].scale_factor_ppm, -200, 4 * g2.at("scale_factor_sigma_ppm").get<double>());
  EXPECT_EQ(g2.at("covariance").size(), 4u);
  EXPECT_GE(g2.at("terms").size(), 6u);
  // The calibrated unit is read by fuse like any unit.json.
  ASSERT_EQ(Ssiu("simulate gyro --unit " + dir_ + "/truth.json --profile slew --duration-s 120 --seed 6 --out " + dir_ +
                     "/slew",
                 &out),
            0)
      << out;
  EXPECT_EQ(Ssiu("fuse --gyro " + dir_ + "/slew/gyro.csv --st " + dir_ + "/slew/st.csv --unit " + dir_ +
                     "/unit.json --json " + dir_ + "/f.json",
                 &out),
            0)
      << out;
}

TEST_F(FogUnitCli, MissingReferenceColumnExits1WithOneLine) {
  std::ofstream(dir_ + "/nominal.json") << R"({"gyros": [{"axis": [1,0,0]}, {"axis": [0,1,0]}, {"axis": [0,0,1]}]})";
  std::ofstream log(dir_ + "/log.csv");
  log << "t_s,g1_dph,g2_dph,g3_dph,ref_x_dph,ref_y_dph\n";
  for (int k = 1; k <= 20; ++k) log << k << ",1,2,3,1,2\n";
  log.close();
  std::string out;
  EXPECT_EQ(
      Ssiu("fog unit-calibrate " + dir_ + "/log.csv --unit " + dir_ + "/nominal.json --out " + dir_ + "/u.json", &out),
      1);
  EXPECT_NE(out.find("ref_z_dph"), std::string::npos) << out;
  EXPECT_NE(out.find("log.csv"), std::string::npos) << out;
}

}  // namespace
}  // namespace ssiu
