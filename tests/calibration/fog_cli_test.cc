// `ssiu fog ...` end to end: outputs and one-line errors with exit status 1 on bad input.
#include <filesystem>
#include <fstream>

#include "core/json.h"
#include "sim/fog_bench_sim.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

class FogCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(testing::SsiuProgram())) GTEST_SKIP() << "the ssiu program is not built";
    dir_ = testing::TempDir("fog");
  }
  int Ssiu(const std::string& args, std::string* out) { return testing::Run(testing::SsiuProgram() + " " + args, out); }
  static int Lines(const std::string& s) {
    int n = 0;
    for (char c : s) n += c == '\n';
    return n;
  }
  void Write(const std::string& name, const std::string& text) { std::ofstream(dir_ + "/" + name) << text; }
  std::string dir_;
};

TEST_F(FogCli, ThermalFitThenCompensate) {
  ThermalBenchOptions o;
  o.drift = CampaignDriftModel();
  o.duration_s = 300 * 60;
  for (int s = 1; s <= 3; ++s) {
    o.seed = s;
    WriteThermalRunCsv(dir_ + "/run" + std::to_string(s) + ".csv", SimulateThermalRun(o));
  }
  std::string out;
  ASSERT_EQ(Ssiu("fog thermal " + dir_ + "/run1.csv " + dir_ + "/run2.csv --holdout " + dir_ + "/run3.csv --json " +
                     dir_ + "/model.json --plot " + dir_ + "/plots",
                 &out),
            0)
      << out;
  const Json j = ReadJsonFile(dir_ + "/model.json");
  EXPECT_EQ(j.at("tested").size(), 10u);
  EXPECT_TRUE(j.at("terms").contains("K10"));
  EXPECT_GT(j.at("holdout").at("gain").get<double>(), 5.0);
  EXPECT_TRUE(std::filesystem::exists(dir_ + "/plots/holdout_drift.png"));
  EXPECT_TRUE(std::filesystem::exists(dir_ + "/plots/fitted_angle.png"));
  ASSERT_EQ(Ssiu("fog compensate " + dir_ + "/run3.csv --model " + dir_ + "/model.json --out " + dir_ +
                     "/comp.csv --json " + dir_ + "/comp.json",
                 &out),
            0)
      << out;
  EXPECT_NEAR(ReadJsonFile(dir_ + "/comp.json").at("gain").get<double>(), j.at("holdout").at("gain").get<double>(),
              1e-6);
}

TEST_F(FogCli, ThermalBadInputExits1WithOneLine) {
  std::string out;
  Write("unsorted.csv", "t_s,w_dph,ref_dph,temp_c\n0,1,0,20\n2,1,0,20\n1,1,0,20\n");
  EXPECT_EQ(Ssiu("fog thermal " + dir_ + "/unsorted.csv", &out), 1);
  EXPECT_EQ(Lines(out), 1) << out;
  EXPECT_NE(out.find("t_s"), std::string::npos) << out;
  Write("notemp.csv", "t_s,w_dph,ref_dph\n0,1,0\n1,1,0\n");
  EXPECT_EQ(Ssiu("fog thermal " + dir_ + "/notemp.csv", &out), 1);
  EXPECT_EQ(Lines(out), 1) << out;
  EXPECT_NE(out.find("temp_c"), std::string::npos) << out;
  Write("nan.csv", "t_s,w_dph,ref_dph,temp_c\n0,1,0,20\n1,nan,0,20\n2,1,0,20\n");
  EXPECT_EQ(Ssiu("fog thermal " + dir_ + "/nan.csv", &out), 1);
  EXPECT_EQ(Lines(out), 1) << out;
  EXPECT_NE(out.find("w_dph"), std::string::npos) << out;
}

TEST_F(FogCli, MagneticTwoLogsAndBadInput) {
  TurntableOptions o;
  o.fog_x = {0.006, 0.003, 0.0};
  WriteTurntableCsv(dir_ + "/before.csv", SimulateTurntable(o));
  o.fog_x = {};
  o.seed = 2;
  WriteTurntableCsv(dir_ + "/after.csv", SimulateTurntable(o));
  std::string out;
  ASSERT_EQ(Ssiu("fog magnetic " + dir_ + "/before.csv " + dir_ + "/after.csv --json " + dir_ + "/m.json --plot " +
                     dir_ + "/mp",
                 &out),
            0)
      << out;
  const Json j = ReadJsonFile(dir_ + "/m.json");
  EXPECT_FALSE(j.at("consistent_with_zero").get<bool>());
  EXPECT_TRUE(j.at("second").at("consistent_with_zero").get<bool>());
  EXPECT_TRUE(std::filesystem::exists(dir_ + "/mp/magnetic_difference.png"));
  o.positions = 4;
  WriteTurntableCsv(dir_ + "/few.csv", SimulateTurntable(o));
  EXPECT_EQ(Ssiu("fog magnetic " + dir_ + "/few.csv", &out), 1);
  EXPECT_EQ(Lines(out), 1) << out;
  EXPECT_NE(out.find("too few azimuths"), std::string::npos) << out;
  Write("nanaz.csv", "t_s,wx_dph,wy_dph,azimuth_deg\n0,1,1,0\n1,1,1,NaN\n");
  EXPECT_EQ(Ssiu("fog magnetic " + dir_ + "/nanaz.csv", &out), 1);
  EXPECT_EQ(Lines(out), 1) << out;
  // A plot directory that cannot be made: the error is the only line (the summary used to come first).
  EXPECT_EQ(Ssiu("fog magnetic " + dir_ + "/before.csv --plot /proc/ssiu_no_dir", &out), 1);
  EXPECT_EQ(Lines(out), 1) << out;
  EXPECT_NE(out.find("/proc/ssiu_no_dir: cannot create plot directory"), std::string::npos) << out;
}

}  // namespace
}  // namespace ssiu
