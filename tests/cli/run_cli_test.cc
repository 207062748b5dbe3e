// `ssiu run` end to end: a tiny mission config writes the JSON figures and the side outputs; a bad
// config exits 1 with one line naming the file and the field.
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

class RunCli : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::TempDir("run_cli"); }
  std::string Path(const std::string& n) const { return dir_ + "/" + n; }
  void Write(const std::string& n, const std::string& text) const { std::ofstream(Path(n)) << text; }
  std::string dir_;
};

const char* kHead =
    R"({"camera": {"width": 384, "height": 384, "focal_length_px": 1316}, "q_body_sensor": [1, 0, 0, 0]})";

std::string Config(const std::string& fields) {
  return R"({"comment": "tiny mission for the CLI test", "seed": 2, "heads": [)" + std::string(kHead) + "]" + fields +
         "}";
}

TEST_F(RunCli, TinyMissionWritesTheFigures) {
  Write("ssiu.json", Config(R"(, "duration_s": 20, "frame_rate_hz": 0.5, "score_after_s": 5)"));
  const auto r =
      testing::RunSsiu("run --config " + Path("ssiu.json") + " --json " + Path("out.json") + " --out " + Path("out"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("head 1: 11/11 frames solved"));
  const Json j = ReadJsonFile(Path("out.json"));
  for (const char* k : {"status", "frames", "frames_solved", "heads", "star_solution_error", "fused_error", "bias",
                        "faults", "gyros_in_use", "filter", "timing", "config"}) {
    EXPECT_TRUE(j.contains(k)) << k;
  }
  EXPECT_EQ(j["status"], "ok");
  EXPECT_EQ(j["frames"], 11);
  EXPECT_EQ(j["frames_solved"], 11);
  EXPECT_EQ(j["heads"][0]["lost_in_space"], 1);
  EXPECT_EQ(j["heads"][0]["tracking"], 10);
  for (const char* k : {"cross_rms_arcsec", "cross_max_arcsec", "roll_rms_arcsec", "roll_max_arcsec",
                        "within_3sigma_fraction", "nees_mean"}) {
    ASSERT_TRUE(j["fused_error"].contains(k)) << k;
    EXPECT_TRUE(j["fused_error"][k].is_number()) << k;
  }
  // The fused cross-boresight error of a 19-arcsec-per-pixel head is a few arcsec, not degrees.
  EXPECT_LT(j["fused_error"]["cross_rms_arcsec"].get<double>(), 20.0);
  EXPECT_GT(j["fused_error"]["cross_rms_arcsec"].get<double>(), 0.0);
  EXPECT_EQ(j["bias"]["estimate_dph"].size(), 3u);
  EXPECT_EQ(j["gyros_in_use"], Json({1, 2, 3, 4}));
  for (const char* f : {"attitude.csv", "frames.csv", "gyro.csv", "truth.csv", "head1_first.png"}) {
    EXPECT_TRUE(std::filesystem::exists(Path("out/") + f)) << f;
  }
  EXPECT_FALSE(j.contains("unit_calibration"));  // off by default
}

// processor.calibrate_unit: the JSON and the text carry the in-flight unit calibration's state (a
// 30 s slew about one axis: too little for the 12 terms, so not yet estimated), and the config echoes it.
TEST_F(RunCli, CalibrateUnitIsReported) {
  Write("ssiu.json", Config(R"(, "duration_s": 30, "frame_rate_hz": 0.5, "processor": {"calibrate_unit": true})"));
  const auto r = testing::RunSsiu("run --config " + Path("ssiu.json") + " --json " + Path("out.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("unit calibration: "));
  const Json j = ReadJsonFile(Path("out.json"));
  ASSERT_TRUE(j.contains("unit_calibration")) << j.dump();
  const Json& c = j["unit_calibration"];
  EXPECT_TRUE(c["status"] == "accumulating" || c["status"] == "not_observable") << c.dump();
  EXPECT_GT(c["n_windows"].get<int>(), 0) << c.dump();
  EXPECT_TRUE(j["config"]["processor"]["calibrate_unit"].get<bool>());
  Write("bad.json", Config(R"(, "duration_s": 30, "frame_rate_hz": 0.5, "processor": {"calibrate_unit": 1})"));
  const auto bad = testing::RunSsiu("run --config " + Path("bad.json"));
  EXPECT_EQ(bad.status, 1) << bad.output;
  EXPECT_THAT(bad.output, HasSubstr("calibrate_unit"));
}

TEST_F(RunCli, PrintConfigWritesTheBuiltInDefault) {
  const auto r = testing::RunSsiu("run --print-config");
  ASSERT_EQ(r.status, 0) << r.output;
  const Json j = Json::parse(r.output);
  EXPECT_EQ(j["heads"].size(), 2u);
  EXPECT_EQ(j["duration_s"], 120.0);
  // What it prints is a valid config again.
  Write("default.json", r.output);
  const auto again = testing::RunSsiu("run --config " + Path("default.json") + " --print-config");
  ASSERT_EQ(again.status, 0) << again.output;
  EXPECT_EQ(Json::parse(again.output), j);
}

// examples/ssiu_mission.json is the built-in default written out (kept in step with the code).
TEST_F(RunCli, ExampleConfigIsTheBuiltInDefault) {
  const auto ex =
      testing::RunSsiu("run --print-config --config " + testing::SourceDir() + "/examples/ssiu_mission.json");
  ASSERT_EQ(ex.status, 0) << ex.output;
  const auto def = testing::RunSsiu("run --print-config");
  ASSERT_EQ(def.status, 0) << def.output;
  EXPECT_EQ(Json::parse(ex.output), Json::parse(def.output));
}

TEST_F(RunCli, BadConfigExitsOneWithOneLineNamingFileAndField) {
  struct Case {
    const char* file;
    std::string text;
    const char* field;
  } cases[] = {
      {"missing.json", Config(R"(, "frame_rate_hz": 1)"), "duration_s"},
      {"nan.json", Config(R"(, "duration_s": "NaN", "frame_rate_hz": 1)"), "duration_s"},
      {"nan_literal.json", Config(R"(, "duration_s": NaN, "frame_rate_hz": 1)"), "duration_s"},
      {"overflow.json", Config(R"(, "duration_s": 20, "frame_rate_hz": -1e999)"), "1e999"},
      {"rate.json", Config(R"(, "duration_s": 20, "frame_rate_hz": 0)"), "frame_rate_hz"},
      {"four.json",
       R"({"duration_s": 20, "frame_rate_hz": 1, "seed": 1, "heads": [)" + std::string(kHead) + "," + kHead + "," +
           kHead + "," + kHead + "]}",
       "heads"},
      {"camera.json",
       R"({"duration_s": 20, "frame_rate_hz": 1, "seed": 1, "heads": [{"camera": {"width": 384}, "q_body_sensor": [1, 0, 0, 0]}]})",
       "height"},
      {"quat.json",
       R"({"duration_s": 20, "frame_rate_hz": 1, "seed": 1, "heads": [{"camera": {"width": 384, "height": 384, "focal_length_px": 1316}, "q_body_sensor": [0, 0, 0, 0]}]})",
       "q_body_sensor"},
      {"notjson.json", "{\"duration_s\": 20,", "not valid JSON"},
      // Used to fail after the header line, naming the frame simulator's rate_x_dps.
      {"fast.json", Config(R"(, "duration_s": 20, "frame_rate_hz": 1, "motion": {"type": "slew", "rate_dps": 100})"),
       "field 'motion': the body rate reaches 100"},
  };
  for (const auto& c : cases) {
    Write(c.file, c.text);
    const auto r = testing::RunSsiu("run --config " + Path(c.file) + " --json " + Path("x.json"));
    EXPECT_EQ(r.status, 1) << c.file << "\n" << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_THAT(r.output, HasSubstr(c.file));
    EXPECT_THAT(r.output, HasSubstr(c.field)) << r.output;
  }
  const auto r = testing::RunSsiu("run --config " + Path("absent.json"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.output, HasSubstr("absent.json"));
  // An output directory that cannot be made: one line before the mission runs (was a filesystem
  // exception, exit 2, after the header line).
  const auto o = testing::RunSsiu("run --out /proc/ssiu_no_such_dir");
  EXPECT_EQ(o.status, 1) << o.output;
  EXPECT_EQ(std::count(o.output.begin(), o.output.end(), '\n'), 1) << o.output;
  EXPECT_THAT(o.output, HasSubstr("/proc/ssiu_no_such_dir: cannot create output directory"));
}

}  // namespace
}  // namespace ssiu
