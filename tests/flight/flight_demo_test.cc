// The integrator's path end to end (issue 26 item 4): `ssiu run --out DIR --write-frames` writes a
// mission's frames, logs, flight.cfg and catalog blob; examples/flight's C program replays them
// through the C interface only and ends where `ssiu run` ended, against the same truth.
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/csv.h"
#include "core/json.h"
#include "flight/ssiu_flight.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

std::string DemoProgram() {
  return std::filesystem::path(testing::SsiuProgram()).parent_path().string() + "/ssiu-flight-demo";
}

TEST(FlightDemo, ReplaysTheWrittenMissionAsSsiuRunDid) {
  const std::string dir = testing::TempDir("flight_demo");
  std::ofstream(dir + "/ssiu.json") << R"({"seed": 4, "duration_s": 12, "frame_rate_hz": 1, "score_after_s": 4,
    "heads": [{"camera": {"width": 512, "height": 512, "focal_length_px": 1754.8162132636639,
                          "vignetting": 0.2, "hot_pixels": [[10, 20], [300, 301]]}, "q_body_sensor": [1, 0, 0, 0]},
              {"camera": {"width": 512, "height": 512, "focal_length_px": 1754.8162132636639},
               "q_body_sensor": [0.7071067811865476, 0.7071067811865476, 0, 0]}]})";
  const auto run = testing::RunSsiu("run --config " + dir + "/ssiu.json --json " + dir + "/run.json --out " + dir +
                                    "/out --write-frames");
  ASSERT_EQ(run.status, 0) << run.output;
  for (const char* f : {"flight.cfg", "catalog/catalog.bin", "catalog/meta.json", "frames/head1_00000.pgm",
                        "frames/head2_00012.pgm", "gyro.csv", "frames.csv", "truth.csv"})
    EXPECT_TRUE(std::filesystem::exists(dir + "/out/" + f)) << f;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out/frames/head1_00013.pgm"));
  // Head 1's camera extras go with the unit (the replay below uses them as `ssiu run` did).
  std::stringstream cfg;
  cfg << std::ifstream(dir + "/out/flight.cfg").rdbuf();
  EXPECT_THAT(cfg.str(), HasSubstr("head1.vignetting 0.20000000000000001\nhead1.hot_pixels 2 10 20 300 301\n"));
  EXPECT_THAT(cfg.str(), HasSubstr("head2.vignetting 0\nhead2.hot_pixels 0\n"));

  std::string out;
  ASSERT_EQ(testing::Run(DemoProgram() + " " + dir + "/out --json " + dir + "/demo.json --csv " + dir + "/demo.csv",
                         &out),
            0)
      << out;
  const Json d = ReadJsonFile(dir + "/demo.json");
  const Json r = ReadJsonFile(dir + "/run.json");
  EXPECT_EQ(d["frames_processed"], 13);
  EXPECT_EQ(d["frames_solved"], r["frames_solved"]);
  EXPECT_EQ(d["status"], r["status"]);
  EXPECT_EQ(d["gyro_rejected"], 0);
  EXPECT_TRUE(d["frame_ms_mean"].is_number());
  EXPECT_GE(d["frame_ms_max"].get<double>(), d["frame_ms_mean"].get<double>());
  // The same inputs in the same order give the same final attitude, so the same error against the
  // simulator's truth (truth.csv there, the simulation itself here).
  EXPECT_EQ(d["t_s"], r["final"]["t_s"]);
  EXPECT_NEAR(d["attitude_error_arcsec"].get<double>(), r["final"]["error_arcsec"].get<double>(), 1e-3);
  EXPECT_LT(d["attitude_error_arcsec"].get<double>(), 10.0);
  // Per frame set, the matched stars are those `ssiu run` recorded.
  const CsvTable demo = ReadCsv(dir + "/demo.csv"), frames = ReadCsv(dir + "/out/frames.csv");
  ASSERT_EQ(demo.rows(), frames.rows());
  EXPECT_EQ(demo.Column("head1_matches"), frames.Column("head1_matches"));
  EXPECT_EQ(demo.Column("head2_matches"), frames.Column("head2_matches"));
  // --frames N stops after N frame sets.
  ASSERT_EQ(testing::Run(DemoProgram() + " " + dir + "/out --frames 3 --json -", &out), 0) << out;
  EXPECT_THAT(out, HasSubstr("\"frames_processed\": 3"));
  // A directory without flight.cfg: one line naming the file, exit 1.
  EXPECT_EQ(testing::Run(DemoProgram() + " " + dir, &out), 1);
  EXPECT_THAT(out, HasSubstr("flight.cfg"));
}

// A head listing more hot pixels than the C configuration holds: `ssiu run --write-frames` says so in one
// line naming the mission file, exit 1, before the mission runs (no frame written).
TEST(FlightDemo, UnitTheInterfaceCannotCarryIsRefusedBeforeTheRun) {
  const std::string dir = testing::TempDir("flight_demo_hot");
  Json hot = Json::array();
  for (int k = 0; k < SSIU_FLIGHT_MAX_HOT_PIXELS + 1; ++k) hot.push_back({k % 500, 1 + k / 500});
  const Json mission = {
      {"seed", 4},
      {"duration_s", 4},
      {"frame_rate_hz", 1},
      {"score_after_s", 2},
      {"heads",
       {{{"camera", {{"width", 512}, {"height", 512}, {"focal_length_px", 1754.8162132636639}, {"hot_pixels", hot}}},
         {"q_body_sensor", {1, 0, 0, 0}}}}}};
  std::ofstream(dir + "/ssiu.json") << mission.dump();
  const auto run = testing::RunSsiu("run --config " + dir + "/ssiu.json --out " + dir + "/out --write-frames");
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.output, HasSubstr(dir + "/ssiu.json: flight config: head1: more than 256 hot pixels"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/out/frames"));
  // Without --write-frames the C++ processor takes the list.
  EXPECT_EQ(testing::RunSsiu("run --config " + dir + "/ssiu.json").status, 0);
}

// From outside the process (issue 26's acceptance): valgrind's count of the demo's heap allocations
// is the same for 20 and for 60 frame sets of one mission, so nothing in the loop allocates per frame
// (the demo's own I/O included).
long HeapAllocations(const std::string& command) {
  std::string out;
  EXPECT_EQ(testing::Run("valgrind --error-exitcode=3 " + command, &out), 0) << out;
  const auto at = out.find("total heap usage: ");
  if (at == std::string::npos) {
    ADD_FAILURE() << out;
    return -1;
  }
  std::string n;
  for (size_t i = at + 18; i < out.size() && (std::isdigit(static_cast<unsigned char>(out[i])) || out[i] == ','); ++i)
    if (out[i] != ',') n += out[i];
  return std::stol(n);
}

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SSIU_TEST_UNDER_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define SSIU_TEST_UNDER_ASAN 1
#endif
#if defined(SSIU_TEST_UNDER_ASAN)
constexpr bool kUnderAsan = true;
#else
constexpr bool kUnderAsan = false;
#endif

TEST(FlightDemo, HeapAllocationsDoNotGrowWithTheFrames) {
  if (kUnderAsan) GTEST_SKIP() << "under AddressSanitizer valgrind cannot run the demo (the normal build checks it)";
  std::string out;
  if (testing::Run("valgrind --version", &out) != 0) GTEST_SKIP() << "valgrind not installed (scripts/setup.sh installs it)";
  const std::string dir = testing::TempDir("flight_demo_heap");
  std::ofstream(dir + "/ssiu.json") << R"({"seed": 9, "duration_s": 30, "frame_rate_hz": 2, "score_after_s": 4,
    "heads": [{"camera": {"width": 512, "height": 512, "focal_length_px": 1754.8162132636639,
                          "vignetting": 0.2, "hot_pixels": [[10, 20], [300, 301]]}, "q_body_sensor": [1, 0, 0, 0]},
              {"camera": {"width": 512, "height": 512, "focal_length_px": 1754.8162132636639},
               "q_body_sensor": [0.7071067811865476, 0.7071067811865476, 0, 0]}]})";
  const auto run = testing::RunSsiu("run --config " + dir + "/ssiu.json --out " + dir + "/out --write-frames");
  ASSERT_EQ(run.status, 0) << run.output;
  const std::string demo = DemoProgram() + " " + dir + "/out --json " + dir + "/demo.json --frames ";
  const long n20 = HeapAllocations(demo + "20");
  const Json d20 = ReadJsonFile(dir + "/demo.json");
  const long n60 = HeapAllocations(demo + "60");
  const Json d60 = ReadJsonFile(dir + "/demo.json");
  EXPECT_EQ(d20["frames_processed"], 20);
  EXPECT_EQ(d60["frames_processed"], 60);
  EXPECT_EQ(d60["frames_solved"], 60);
  std::printf("demo heap allocations: %ld with 20 frame sets, %ld with 60\n", n20, n60);
  EXPECT_GT(n20, 0);
  EXPECT_EQ(n20, n60);
}

}  // namespace
}  // namespace ssiu
