// End-to-end: `ssiu simulate gyro` then `ssiu fuse`, and the CLI's bad-input errors (exit 1).
#include <filesystem>
#include <fstream>

#include "core/csv.h"
#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

class GyroCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(testing::SsiuProgram())) GTEST_SKIP() << "ssiu program not built (ninja ssiu)";
  }
};

TEST_F(GyroCli, SimulateThenFuseRecoversBiases) {
  const std::string d = testing::TempDir("gyrocli");
  {
    std::ofstream(d + "/unit.json") << R"({"rate_hz": 20, "default": {"bias_instability_dph": 0},
      "gyros": [{"axis": [1,0,0], "bias_dph": 2}, {"axis": [0,1,0], "bias_dph": -3},
                {"axis": [0,0,1], "bias_dph": 1.5}, {"axis": [1,1,1], "bias_dph": 2.5}]})";
    std::ofstream(d + "/profile.json") << R"({"type": "slew", "rate_dps": 0.1, "axis": [0, 0.6, 0.8]})";
  }
  std::string out;
  const std::string ssiu = testing::SsiuProgram();
  ASSERT_EQ(testing::Run(ssiu + " simulate gyro --unit " + d + "/unit.json --profile " + d +
                             "/profile.json --duration-s 1800 --seed 5 --out " + d + "/sim",
                         &out),
            0)
      << out;
  for (const char* f : {"gyro.csv", "truth.csv", "rates.csv", "st.csv", "unit.json"}) {
    EXPECT_TRUE(std::filesystem::exists(d + "/sim/" + f)) << f;
  }
  ASSERT_EQ(testing::Run(ssiu + " fuse --gyro " + d + "/sim/gyro.csv --st " + d + "/sim/st.csv --unit " + d +
                             "/sim/unit.json --json " + d + "/fuse.json --out " + d + "/att.csv",
                         &out),
            0)
      << out;
  const Json j = ReadJsonFile(d + "/fuse.json");
  EXPECT_EQ(j["status"], "fused");
  EXPECT_TRUE(j["faults"].empty());
  // True body biases of this unit: (H'H)^-1 H' b.
  const CsvTable rates = ReadCsv(d + "/sim/rates.csv");
  const char* names[3] = {"bx_dph", "by_dph", "bz_dph"};
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(j["bias_dph"][a].get<double>(), rates.Column(names[a]).back(),
                4 * j["bias_sigma_dph"][a].get<double>());
    EXPECT_LT(j["bias_sigma_dph"][a].get<double>(), 0.03);
  }
  const CsvTable att = ReadCsv(d + "/att.csv");
  EXPECT_EQ(att.rows(), 36000u);
  EXPECT_TRUE(att.Has("sigma_z_arcsec"));
}

TEST_F(GyroCli, BadInputExitsOneWithALineNamingFileAndField) {
  const std::string d = testing::TempDir("gyrocli_bad");
  const std::string ssiu = testing::SsiuProgram();
  std::ofstream(d + "/st.csv") << "t_s,qw,qx,qy,qz\n0,1,0,0,0\n1,1,0,0,0\n";
  std::ofstream(d + "/missing.csv") << "t_s,wx_dph,wy_dph\n0.5,1,2\n1.0,1,2\n";
  std::ofstream(d + "/nan.csv") << "t_s,wx_dph,wy_dph,wz_dph\n0.5,1,2,3\n1.0,1,NaN,3\n";
  std::ofstream(d + "/unsorted.csv") << "t_s,wx_dph,wy_dph,wz_dph\n1.0,1,2,3\n0.5,1,2,3\n";
  struct Case {
    const char* file;
    const char* field;
  } cases[] = {{"missing.csv", "wz_dph"}, {"nan.csv", "wy_dph"}, {"unsorted.csv", "t_s"}};
  for (const auto& c : cases) {
    std::string out;
    const int rc = testing::Run(ssiu + " fuse --gyro " + d + "/" + c.file + " --st " + d + "/st.csv --json -", &out);
    EXPECT_EQ(rc, 1) << out;
    EXPECT_THAT(out, HasSubstr(c.file));
    EXPECT_THAT(out, HasSubstr(c.field));
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  }
  std::string out;
  EXPECT_EQ(testing::Run(ssiu + " simulate gyro --profile " + d + "/nope.json --out " + d + "/x", &out), 1) << out;
  EXPECT_THAT(out, HasSubstr("nope.json"));
  // A star tracker at 1e9 Hz used to run for hours.
  std::ofstream(d + "/fast_st.json") << R"({"type": "slew", "star_tracker": {"rate_hz": 1e9}})";
  EXPECT_EQ(
      testing::Run(ssiu + " simulate gyro --profile " + d + "/fast_st.json --duration-s 10 --out " + d + "/x", &out), 1)
      << out;
  EXPECT_THAT(out, HasSubstr("star_tracker.rate_hz must be in (0, 1000]"));
  // A reversed outage used to be accepted as no outage.
  std::ofstream(d + "/reversed.json") << R"({"type": "slew", "star_tracker": {"outages_s": [[8, 3]]}})";
  EXPECT_EQ(
      testing::Run(ssiu + " simulate gyro --profile " + d + "/reversed.json --duration-s 10 --out " + d + "/x", &out),
      1)
      << out;
  EXPECT_THAT(out, HasSubstr("reversed.json"));
  EXPECT_THAT(out, HasSubstr("outages_s"));
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
}

}  // namespace
}  // namespace ssiu
