// `ssiu fuse --noise` and the noise flags: the allan -> fuse chain on a few runs (20 in
// fuse_noise_chain_longtest.cc) and the bad input the command must refuse.
#include "sim/fuse_noise_chain.h"

#include <algorithm>
#include <fstream>

namespace ssiu {
namespace {

using ::testing::HasSubstr;

// 8 runs: the RMS over 24 axis-runs scatters by about 1 / sqrt(48) = 14%, so the CI bound is 1.5x
// (chi^2(24) beyond 1.5^2 * 24: p = 4e-4); the long test holds the issue's 1.2x over 20 runs.
TEST(FuseNoiseChain, AllanNoiseFileBringsTheBiasToTheArwBound) {
  const testing::NoiseChainScore s = testing::RunNoiseChain(8, testing::TempDir("fuse_noise_chain"), false);
  EXPECT_EQ(s.noise.at("source"), "noise_file");
  EXPECT_NEAR(s.noise.at("arw_deg_per_sqrt_h").get<double>(), 0.01, 0.001);  // measured by allan on 2 h
  for (int a = 0; a < 3; ++a) {
    EXPECT_LT(s.bias_rms_dph[a], 1.5 * s.crb_dph) << "axis " << a;
    EXPECT_GT(s.bias_rms_dph[a], 0.5 * s.crb_dph) << "axis " << a;
  }
  // Consistency: mean of 8 chi^2(3) is chi^2(24) / 8, 99% two-sided [1.23, 5.6].
  EXPECT_GT(s.nees_mean, 1.23);
  EXPECT_LT(s.nees_mean, 5.6);
}

// A 30-min calibration log: its last octaves hold a few Allan clusters, where `ssiu allan` used to read a
// flicker floor (0.056 deg/h on x with this seed) out of white noise; the filter then let the bias walk
// at 0.18 deg/h/sqrt(h) and the error was 1.4x the bound here (1.9x on the issue's held-out case).
TEST(FuseNoiseChain, ShortCalibrationLogGivesNoSpuriousBiasWalk) {
  const testing::NoiseChainScore s = testing::RunNoiseChain(8, testing::TempDir("fuse_noise_short"), false, 1800);
  EXPECT_EQ(s.noise.at("bias_instability_dph").get<double>(), 0.0);
  EXPECT_EQ(s.noise.at("rrw_dph_per_sqrt_h").get<double>(), 0.0);
  for (int a = 0; a < 3; ++a) EXPECT_LT(s.bias_rms_dph[a], 1.5 * s.crb_dph) << "axis " << a;
  EXPECT_GT(s.nees_mean, 1.23);
  EXPECT_LT(s.nees_mean, 5.6);
}

TEST(FuseNoiseChain, FlagsOverrideTheFileAndBadNoiseIsRefused) {
  const std::string d = testing::TempDir("fuse_noise_flags");
  const double bias[3] = {1, 2, 3};
  testing::WriteStaticBodyRateLog(d + "/g.csv", 10, 60, 0.01, bias, 1);
  testing::WriteStaticStarLog(d + "/st.csv", 60, 2);
  std::ofstream(d + "/n.json") << R"({"terms": {"arw_deg_per_sqrt_h": {"value": 0.02, "significant": true},
    "bias_instability_dph": {"value": 0.003, "significant": true},
    "rrw_deg_per_h_per_sqrt_h": {"value": 0.5, "significant": false}}})";
  const std::string fuse = "fuse --gyro " + d + "/g.csv --st " + d + "/st.csv --json " + d + "/f.json ";
  testing::SsiuResult r = testing::RunSsiu(fuse + "--noise " + d + "/n.json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("noise (noise_file)"));
  Json n = ReadJsonFile(d + "/f.json").at("noise");
  EXPECT_EQ(n.at("source"), "noise_file");
  EXPECT_DOUBLE_EQ(n.at("arw_deg_per_sqrt_h").get<double>(), 0.02);
  EXPECT_DOUBLE_EQ(n.at("bias_instability_dph").get<double>(), 0.003);
  EXPECT_DOUBLE_EQ(n.at("rrw_dph_per_sqrt_h").get<double>(), 0.0);  // not significant
  EXPECT_DOUBLE_EQ(n.at("init_bias_sigma_dph").get<double>(), 10.0);
  r = testing::RunSsiu(fuse + "--noise " + d +
                       "/n.json --arw-deg-per-sqrt-h 0.005 --rrw-dph-per-sqrt-h 0.001 "
                       "--init-bias-sigma-dph 3");
  ASSERT_EQ(r.status, 0) << r.output;
  n = ReadJsonFile(d + "/f.json").at("noise");
  EXPECT_EQ(n.at("source"), "flags");
  EXPECT_DOUBLE_EQ(n.at("arw_deg_per_sqrt_h").get<double>(), 0.005);
  EXPECT_DOUBLE_EQ(n.at("bias_instability_dph").get<double>(), 0.003);
  EXPECT_DOUBLE_EQ(n.at("rrw_dph_per_sqrt_h").get<double>(), 0.001);
  EXPECT_DOUBLE_EQ(n.at("init_bias_sigma_dph").get<double>(), 3.0);
  // Without either: the default unit's noise, said so.
  r = testing::RunSsiu(fuse);
  ASSERT_EQ(r.status, 0) << r.output;
  n = ReadJsonFile(d + "/f.json").at("noise");
  EXPECT_EQ(n.at("source"), "default_unit");
  EXPECT_DOUBLE_EQ(n.at("bias_instability_dph").get<double>(), 0.05);

  // Bad input: one line naming the flag, or the file and key; exit 1.
  std::ofstream(d + "/no_terms.json") << R"({"tau_s": [1, 2], "adev": [0.1, 0.05]})";
  std::ofstream(d + "/no_sig.json") << R"({"terms": {"arw_deg_per_sqrt_h": {"value": 0.01},
    "bias_instability_dph": {"value": 0, "significant": false},
    "rrw_deg_per_h_per_sqrt_h": {"value": 0, "significant": false}}})";
  std::ofstream(d + "/str.json") << R"([{"terms": {"arw_deg_per_sqrt_h": {"value": "0.01", "significant": true},
    "bias_instability_dph": {"value": 0, "significant": false},
    "rrw_deg_per_h_per_sqrt_h": {"value": 0, "significant": false}}}])";
  const std::pair<std::string, std::string> bad[] = {
      {"--arw-deg-per-sqrt-h -0.01", "--arw-deg-per-sqrt-h: must be a finite number > 0"},
      {"--bias-instability-dph nan", "--bias-instability-dph: must be a finite number >= 0"},
      {"--rrw-dph-per-sqrt-h -1", "--rrw-dph-per-sqrt-h: must be a finite number >= 0"},
      {"--init-bias-sigma-dph 0", "--init-bias-sigma-dph: must be a finite number > 0"},
      {"--noise " + d + "/no_terms.json", d + "/no_terms.json: missing object 'terms'"},
      {"--noise " + d + "/no_sig.json", "terms.arw_deg_per_sqrt_h.significant' is missing"},
      {"--noise " + d + "/str.json", "[0].terms.arw_deg_per_sqrt_h: field 'value' is not a number"},
      {"--noise " + d + "/none.json", d + "/none.json: cannot open file"},
  };
  for (const auto& [args, msg] : bad) {
    r = testing::RunSsiu(fuse + args);
    EXPECT_EQ(r.status, 1) << args << ": " << r.output;
    EXPECT_THAT(r.output, HasSubstr(msg)) << args;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  }
}

}  // namespace
}  // namespace ssiu
