#include <fstream>

#include "analysis/discover_gyro.h"
#include "core/csv.h"
#include "core/error.h"
#include "core/json.h"
#include "discover_gyro_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::ssiu::testing::RunGyroMonteCarlo;

// Small version of the 60-log acceptance (discover_gyro_longtest.cc): 12 generated cases.
TEST(DiscoverGyro, TwelveHiddenCausesFoundOrNone) {
  const auto s = RunGyroMonteCarlo(12, 1001, false);
  EXPECT_GE(s.right_cause, s.with_cause - 1) << "right cause in " << s.right_cause << " of " << s.with_cause;
  EXPECT_EQ(s.clean_none, s.clean);
  EXPECT_EQ(s.named_gain_above_1, s.named);
  EXPECT_GE(s.params_within_3_sigma, s.params_checked - 1);
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

void WriteLog(const std::string& path, const GyroBenchLog& log, bool with_ref = true) {
  std::vector<std::string> header = {"t_s", "w_dph", "temp_c"};
  std::vector<std::vector<double>> cols = {log.t_s, log.w_dph, log.temp_c};
  if (with_ref) header.push_back("ref_dph"), cols.push_back(log.ref_dph);
  if (!log.azimuth_deg.empty()) header.push_back("azimuth_deg"), cols.push_back(log.azimuth_deg);
  WriteCsv(path, header, cols);
}

TEST(DiscoverGyroCli, FindsMagneticHarmonicAndWritesJson) {
  // A harmonic with phase near 0 or 180 deg is what an azimuth misalignment produces (nested,
  // indistinguishable in one axis): take a case whose phase is well away from it.
  uint64_t seed = 77;
  while (std::abs(std::sin(testing::MakeGyroCase("magnetic_field", seed).truth.at("phase_deg") * kDegToRad)) < 0.7) ++seed;
  const auto c = testing::MakeGyroCase("magnetic_field", seed);
  const std::string dir = testing::TempDir("discover_gyro_cli");
  WriteLog(dir + "/static.csv", c.logs[0]);
  WriteLog(dir + "/rate.csv", c.logs[1]);
  std::string out;
  const int rc = testing::Run(testing::SsiuProgram() + " discover gyro " + dir + "/static.csv " + dir +
                                  "/rate.csv --json " + dir + "/d.json",
                              &out);
  ASSERT_EQ(rc, 0) << out;
  const Json j = ReadJsonFile(dir + "/d.json");
  ASSERT_EQ(j["cause"], "magnetic_field") << j.dump(1);
  const double amp = j["parameters"]["amplitude_dph"].get<double>();
  EXPECT_NEAR(amp, c.truth.at("amplitude_dph"), 3 * j["parameter_sigmas"]["amplitude_dph"].get<double>());
  EXPECT_GT(j["gain"].get<double>(), 1.0);
  EXPECT_GE(j["candidates"].size(), 8u);
}

TEST(DiscoverGyroCli, BadInputExitsOneNamingTheField) {
  const auto c = testing::MakeGyroCase("none", 5);
  const std::string dir = testing::TempDir("discover_gyro_bad");
  WriteLog(dir + "/noref.csv", c.logs[0], false);
  std::string out;
  EXPECT_EQ(testing::Run(testing::SsiuProgram() + " discover gyro " + dir + "/noref.csv", &out), 1);
  EXPECT_THAT(out, ::testing::HasSubstr("ref_dph"));
  GyroBenchLog unsorted = c.logs[0];
  std::swap(unsorted.t_s[10], unsorted.t_s[11]);
  WriteLog(dir + "/unsorted.csv", unsorted);
  EXPECT_EQ(testing::Run(testing::SsiuProgram() + " discover gyro " + dir + "/unsorted.csv", &out), 1);
  EXPECT_THAT(out, ::testing::HasSubstr("t_s"));
  GyroBenchLog tiny = c.logs[0];
  tiny.t_s.resize(20), tiny.w_dph.resize(20), tiny.ref_dph.resize(20), tiny.temp_c.resize(20), tiny.azimuth_deg.resize(20);
  WriteLog(dir + "/tiny.csv", tiny);
  EXPECT_EQ(testing::Run(testing::SsiuProgram() + " discover gyro " + dir + "/tiny.csv", &out), 1);
  EXPECT_THAT(out, ::testing::HasSubstr("too few rows"));
}

TEST(DiscoverGyro, OptionsCheckRejectsBadValues) {
  GyroDiscoverOptions o;
  o.alpha = 0.7;
  EXPECT_THROW(o.Check(), InputError);
  o = {};
  o.cv_blocks = 1;
  EXPECT_THROW(o.Check(), InputError);
}

}  // namespace
}  // namespace ssiu
