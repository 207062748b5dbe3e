// JPEG frames end to end: the real GranaSAT frames (../shared/data/granasat, a DMK 41 camera with a
// 12 mm lens, 27 x 21 deg, 8-bit grey baseline JPEG). `ssiu calibrate` on the JPEGs from a nominal
// guess gives a camera with which every frame solves, and `ssiu solve` of each JPEG equals the solve
// of a lossless PNG copy of the pixels as OpenCV's decoder reads them.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// The solve JSON without what names the input or measures the run.
Json Solution(const std::string& path) {
  Json j = ReadJsonFile(path);
  j.erase("timing_ms");
  j.erase("file");
  return j;
}

TEST(JpegCli, GranasatCalibratesAndEverySolveEqualsItsPngCopy) {
  SSIU_REQUIRE_SHARED(dir, "granasat");
  const std::string tmp = testing::TempDir("jpeg_cli");
  std::vector<std::string> jpegs;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() == ".jpg") jpegs.push_back(e.path().string());
  }
  std::sort(jpegs.begin(), jpegs.end());
  ASSERT_GE(jpegs.size(), 10u);
  std::string list;
  for (const auto& j : jpegs) list += " " + j;
  // 12 mm lens, 4.65 um pixels: f = 2580 px, centred.
  std::ofstream(tmp + "/guess.json") << R"({"width": 1280, "height": 960, "focal_length_px": 2580})";
  const auto cal = testing::RunSsiu("calibrate" + list + " --camera " + tmp + "/guess.json --out " + tmp +
                                    "/cam.json --json " + tmp + "/report.json");
  ASSERT_EQ(cal.status, 0) << cal.output;
  const Json rep = ReadJsonFile(tmp + "/report.json");
  EXPECT_GE(rep["frames_solved"].get<int>(), static_cast<int>(jpegs.size()) - 2);  // its last pass
  for (const auto& j : jpegs) {
    const std::string png = tmp + "/" + std::filesystem::path(j).stem().string() + ".png";
    ASSERT_TRUE(cv::imwrite(png, cv::imread(j, cv::IMREAD_UNCHANGED)));
    const auto a = testing::RunSsiu("solve " + j + " --camera " + tmp + "/cam.json --json " + tmp + "/a.json");
    const auto b = testing::RunSsiu("solve " + png + " --camera " + tmp + "/cam.json --json " + tmp + "/b.json");
    ASSERT_EQ(a.status, 0) << a.output;
    ASSERT_EQ(b.status, 0) << b.output;
    const Json ja = Solution(tmp + "/a.json"), jb = Solution(tmp + "/b.json");
    EXPECT_EQ(ja["status"], "solved") << j;
    EXPECT_EQ(ja, jb) << j;
  }
}

}  // namespace
}  // namespace ssiu
