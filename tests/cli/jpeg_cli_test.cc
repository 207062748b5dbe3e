// JPEG frames end to end: the real GranaSAT frames (../shared/data/granasat, a DMK 41 camera with a
// 12 mm lens, 27 x 21 deg, 8-bit grey baseline JPEG). `ssiu calibrate` on the JPEGs from a nominal
// guess gives a camera with which every frame solves, and `ssiu solve` of each JPEG equals the solve
// of a lossless PNG copy of the pixels as OpenCV's decoder reads them.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// The GranaSAT JPEGs in `dir`, sorted, and `ssiu calibrate` of them all into tmp/cam.json and
// tmp/report.json from the lens's nominal camera (12 mm lens, 4.65 um pixels: f = 2580 px, centred).
std::vector<std::string> CalibrateGranasat(const std::string& dir, const std::string& tmp) {
  std::vector<std::string> jpegs;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() == ".jpg") jpegs.push_back(e.path().string());
  }
  std::sort(jpegs.begin(), jpegs.end());
  std::string list;
  for (const auto& j : jpegs) list += " " + j;
  std::ofstream(tmp + "/guess.json") << R"({"width": 1280, "height": 960, "focal_length_px": 2580})";
  const auto cal = testing::RunSsiu("calibrate" + list + " --camera " + tmp + "/guess.json --out " + tmp +
                                    "/cam.json --json " + tmp + "/report.json");
  EXPECT_EQ(cal.status, 0) << cal.output;
  return jpegs;
}

TEST(JpegCli, GranasatCalibratesAndEverySolveEqualsItsPngCopy) {
  if (testing::kUnderSanitizer)
    GTEST_SKIP() << "a calibration of every frame (too long for the sanitizer run's share of CI time); the JPEG "
                    "decoder runs there in "
                    "RasterCodec.JpegAndBmpMatchOpenCv and DetectJpeg.*, the calibration of real "
                    "frames in CalibrateCli.SwarmFramesFromANominalGuessAllSolve, the batch solve in BatchCli.*";
  SSIU_REQUIRE_SHARED(dir, "granasat");
  const std::string tmp = testing::TempDir("jpeg_cli");
  const std::vector<std::string> jpegs = CalibrateGranasat(dir, tmp);
  ASSERT_GE(jpegs.size(), 10u);
  ASSERT_FALSE(::testing::Test::HasFailure());
  const Json rep = ReadJsonFile(tmp + "/report.json");
  EXPECT_GE(rep["frames_solved"].get<int>(), static_cast<int>(jpegs.size()) - 2);  // its last pass
  // Both sets solved in one batch each (--jsonl: one record per input, in input order, equal to its own
  // `ssiu solve --json`: BatchCli.SolveBatchEqualsSingleSolvesInOrderWithAnErrorRecord).
  std::string jpeg_list, png_list;
  for (const auto& j : jpegs) {
    const std::string png = tmp + "/" + std::filesystem::path(j).stem().string() + ".png";
    ASSERT_TRUE(cv::imwrite(png, cv::imread(j, cv::IMREAD_UNCHANGED)));
    jpeg_list += " " + j;
    png_list += " " + png;
  }
  const std::string cam = " --camera " + tmp + "/cam.json --threads 2 --jsonl ";
  const auto a = testing::RunSsiu("solve" + jpeg_list + cam + tmp + "/a.jsonl");
  const auto b = testing::RunSsiu("solve" + png_list + cam + tmp + "/b.jsonl");
  ASSERT_EQ(a.status, 0) << a.output;
  ASSERT_EQ(b.status, 0) << b.output;
  std::ifstream fa(tmp + "/a.jsonl"), fb(tmp + "/b.jsonl");
  std::string la, lb;
  size_t records = 0;
  for (; std::getline(fa, la) && std::getline(fb, lb); ++records) {
    Json ja = Json::parse(la), jb = Json::parse(lb);
    EXPECT_EQ(ja["file"], jpegs[records]);
    for (Json* r : {&ja, &jb}) r->erase("timing_ms"), r->erase("file");
    EXPECT_EQ(ja["status"], "solved") << jpegs[records];
    EXPECT_EQ(ja, jb) << jpegs[records];
  }
  EXPECT_EQ(records, jpegs.size());
}

// The principal point refitted from one frame (IdentifyOptions::refine_principal_p): given the lens's
// focal lengths with the principal point at the image centre, each GranaSAT frame's stars move it
// where `ssiu calibrate`'s joint fit of all frames puts it (671, 438 px: 32 px right of and 42 px
// above the centre), within 3 sigma of the two fits combined.
TEST(JpegCli, GranasatPrincipalPointFromOneFrameAgreesWithTheCalibration) {
  if (testing::kUnderSanitizer)
    GTEST_SKIP() << "a calibration of every frame and a solve of each (too long for the sanitizer run's share of CI "
                    "time); the calibration of "
                    "real frames runs there in CalibrateCli.SwarmFramesFromANominalGuessAllSolve, the JPEG decoder in "
                    "RasterCodec.JpegAndBmpMatchOpenCv, the principal point's refit in "
                    "RefinePrincipalPoint.ThirtyPixelsOffCentreAreFoundAndARightCameraKeepsItsOwn";
  SSIU_REQUIRE_SHARED(dir, "granasat");
  const std::string tmp = testing::TempDir("jpeg_pp");
  const std::vector<std::string> jpegs = CalibrateGranasat(dir, tmp);
  ASSERT_FALSE(::testing::Test::HasFailure());
  Json cam = ReadJsonFile(tmp + "/cam.json");
  const double cx = cam["principal_point"][0].get<double>(), cy = cam["principal_point"][1].get<double>();
  const Json rep = ReadJsonFile(tmp + "/report.json");
  const double cal_sigma_px = std::hypot(rep["parameters"]["cx_px"]["sigma"].get<double>(),
                                         rep["parameters"]["cy_px"]["sigma"].get<double>());
  cam["principal_point"] = {639.5, 479.5};
  WriteJsonFile(tmp + "/centred.json", cam);
  int refined = 0, agree = 0;
  for (const auto& j : jpegs) {
    const auto a = testing::RunSsiu("solve " + j + " --camera " + tmp + "/centred.json --json " + tmp + "/a.json");
    ASSERT_EQ(a.status, 0) << a.output;
    const Json s = ReadJsonFile(tmp + "/a.json");
    if (!s["principal_point_refined"].get<bool>()) continue;
    ++refined;
    const double sigma = std::hypot(s["principal_point_sigma_px"].get<double>(), cal_sigma_px);
    const double d = std::hypot(s["cx_px"].get<double>() - cx, s["cy_px"].get<double>() - cy);
    agree += d < 3 * sigma;
    std::printf("%s: (%.1f, %.1f) +- %.1f px, %.1f px from the calibration's\n", j.c_str(), s["cx_px"].get<double>(),
                s["cy_px"].get<double>(), s["principal_point_sigma_px"].get<double>(), d);
  }
  std::printf("principal point refined in %d of %zu frames, within 3 sigma of the calibration's %d\n", refined,
              jpegs.size(), agree);
  EXPECT_GE(refined, static_cast<int>(jpegs.size()) - 2);
  EXPECT_GE(agree, refined - 1);
}

}  // namespace
}  // namespace ssiu
