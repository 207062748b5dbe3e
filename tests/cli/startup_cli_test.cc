// A fast start (issue 17): `ssiu` loads OpenCV only when it draws or needs OpenCV's geometry, from the
// module libssiu_opencv.so (core/opencv_edge.h), and libtiff only for a TIFF (core/lazy_library.h); the
// common path (--help, detect, solve of a PNG) loads none of them, and a solve with --overlay loads the
// module and OpenCV and writes an overlay.
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

// The run's output with the dynamic loader's list of the libraries it loaded (LD_DEBUG=libs).
std::string LoadedBy(const std::string& args, int* status) {
  std::string out;
  *status = testing::Run("LD_DEBUG=libs " + testing::SsiuProgram() + " " + args + " 2>&1", &out);
  return out;
}

TEST(StartupCli, CommonPathLoadsNoOpenCvAndAnOverlayLoadsItOnUse) {
  const std::string d = testing::TempDir("startup_cli");
  ASSERT_EQ(testing::RunSsiu("simulate frame --random --seed 17 --out " + d + "/f").status, 0);
  ASSERT_EQ(testing::RunSsiu("catalog build --fov-deg 16.6 --out " + d + "/cat").status, 0);
  int status = -1;
  std::string out = LoadedBy("--help", &status);
  EXPECT_EQ(status, 0);
  EXPECT_THAT(out, HasSubstr("calling init: "));  // the loader did report (else the checks below prove nothing)
  EXPECT_THAT(out, Not(HasSubstr("libopencv")));
  EXPECT_THAT(out, Not(HasSubstr("libtiff")));
  out = LoadedBy("detect " + d + "/f/frame_0000.png --camera " + d + "/f/camera.json --json " + d + "/d.json", &status);
  EXPECT_EQ(status, 0) << out;
  EXPECT_THAT(out, Not(HasSubstr("libopencv")));
  const std::string solve = "solve " + d + "/f/frame_0000.png --camera " + d + "/f/camera.json --catalog " + d +
                            "/cat --json " + d + "/s.json";
  out = LoadedBy(solve, &status);
  EXPECT_EQ(status, 0) << out;
  EXPECT_THAT(out, Not(HasSubstr("libopencv")));
  EXPECT_THAT(out, Not(HasSubstr("libssiu_opencv")));
  EXPECT_THAT(out, Not(HasSubstr("libtiff")));
  out = LoadedBy(solve + " --overlay " + d + "/o.png", &status);
  EXPECT_EQ(status, 0) << out;
  EXPECT_THAT(out, HasSubstr("libssiu_opencv.so"));
  EXPECT_THAT(out, HasSubstr("libopencv_imgproc"));
  const cv::Mat o = cv::imread(d + "/o.png", cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(o.empty());
  EXPECT_EQ(o.cols, 1024);
  EXPECT_EQ(o.channels(), 3);
}

}  // namespace
}  // namespace ssiu
