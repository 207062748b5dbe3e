// `ssiu calibrate` end to end: the real Swarm frames (../shared/data/swarm, pixels about twice as tall
// as wide) from a nominal guess, then every frame solved by `ssiu solve` with the written camera;
// bad input.
#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/camera.h"
#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(CalibrateCli, SwarmFramesFromANominalGuessAllSolve) {
  SSIU_REQUIRE_SHARED(dir, "swarm");
  std::string frames;
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ".png") frames += " " + e.path().string(), ++n;
  ASSERT_GE(n, 10);
  const std::string tmp = testing::TempDir("calibrate_cli");
  // 20 mm lens, 8.6 um pixels, one video field: fx = 2326 px, fy about half (rows 2 x 8.6 um apart).
  std::ofstream(tmp + "/guess.json") << R"({"width": 752, "height": 290, "focal_length_mm": 20, "pixel_pitch_um": 8.6, "focal_length_y_px": 1163})";
  const std::string kstars = "/usr/share/kstars/stars.dat";
  const std::string source = std::ifstream(kstars) ? " --source " + kstars : "";
  const auto r = testing::RunSsiu("calibrate" + frames + " --camera " + tmp + "/guess.json --out " + tmp + "/cam.json --json " +
                                  tmp + "/report.json" + source);
  ASSERT_EQ(r.status, 0) << r.output;
  const Json rep = ReadJsonFile(tmp + "/report.json");
  EXPECT_EQ(rep["status"], "calibrated");
  EXPECT_EQ(rep["frames_solved"].get<int>(), n);
  const Camera cam = LoadCamera(tmp + "/cam.json");
  // Interline CCD read out as one field: fy/fx near 1/2 (8.6 um wide, ~2 x 8.3 um tall pixels).
  EXPECT_NEAR(cam.FocalYPx() / cam.focal_length_px, 0.5, 0.05);
  EXPECT_NEAR(cam.focal_length_px, 2325, 0.03 * 2325);
  EXPECT_LT(rep["held_out"]["rms_after_px"].get<double>(), rep["held_out"]["rms_before_px"].get<double>());
  EXPECT_LT(rep["rms_px"].get<double>(), 0.6);
  // Every frame solves with the written camera through `ssiu solve` (no focal tolerance).
  int solved = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() != ".png") continue;
    const auto s = testing::RunSsiu("solve " + e.path().string() + " --camera " + tmp + "/cam.json --json " + tmp + "/s.json");
    ASSERT_EQ(s.status, 0) << s.output;
    if (ReadJsonFile(tmp + "/s.json")["status"] == "solved") ++solved;
  }
  EXPECT_EQ(solved, n);
  // With square pixels (the guess without fy) `ssiu solve` solves none of them.
  std::ofstream(tmp + "/square.json") << R"({"width": 752, "height": 290, "focal_length_mm": 20, "pixel_pitch_um": 8.6})";
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() != ".png") continue;
    const auto s = testing::RunSsiu("solve " + e.path().string() + " --camera " + tmp + "/square.json --json " + tmp + "/s.json");
    EXPECT_NE(ReadJsonFile(tmp + "/s.json")["status"], "solved") << e.path();
    break;  // one is enough (an unsolvable frame searches its whole hypothesis budget)
  }
}

TEST(CalibrateCli, BadInputNamesTheFlagOrFile) {
  const std::string tmp = testing::TempDir("calibrate_cli_bad");
  auto r = testing::RunSsiu("calibrate " + tmp + "/none.png --out " + tmp + "/cam.json");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.output, ::testing::HasSubstr("--camera"));
  std::ofstream(tmp + "/bad.json") << R"({"width": 752, "height": 290, "focal_length_px": 2325, "focal_length_y_px": -3})";
  r = testing::RunSsiu("calibrate " + tmp + "/none.png --camera " + tmp + "/bad.json --out " + tmp + "/cam.json");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.output, ::testing::HasSubstr("focal_length_y_px"));
}

}  // namespace
}  // namespace ssiu
