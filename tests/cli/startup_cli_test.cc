// A fast start (issue 17): `ssiu` loads OpenCV only when it draws or needs OpenCV's geometry, from the
// module libssiu_opencv.so (core/opencv_edge.h), and libtiff only for a TIFF (core/lazy_library.h); the
// common path (--help, detect, solve of a PNG) loads none of them, and a solve with --overlay loads the
// module and OpenCV and writes an overlay.
#include <algorithm>
#include <filesystem>
#include <fstream>
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
  EXPECT_THAT(out, Not(HasSubstr("libssiu_tools")));
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

// The tool commands are the module libssiu_tools.so (cli/tools_module.h): loaded for one of its
// commands or the whole help, not for the program's own commands; without it, the program's own
// commands still run and a tool command is refused on one line that names the module.
TEST(StartupCli, ToolCommandsLoadTheirModuleOnlyWhenCalled) {
  int status = -1;
  std::string out = LoadedBy("--help", &status);
  EXPECT_EQ(status, 0);
  EXPECT_THAT(out, HasSubstr("libssiu_tools.so"));
  EXPECT_THAT(out, HasSubstr("discover"));
  EXPECT_THAT(out, HasSubstr("groundtest"));
  out = LoadedBy("run --help", &status);
  EXPECT_EQ(status, 0);
  EXPECT_THAT(out, HasSubstr("calling init: "));
  EXPECT_THAT(out, Not(HasSubstr("libssiu_tools")));
  out = LoadedBy("simulate performance --help", &status);
  EXPECT_EQ(status, 0);
  EXPECT_THAT(out, HasSubstr("libssiu_tools.so"));

  const std::string d = testing::TempDir("startup_tools");
  const std::string none = "SSIU_TOOLS_MODULE=" + d + "/none.so ";
  std::string o;
  status = testing::Run(none + testing::SsiuProgram() + " discover gyro x.csv 2>&1", &o);
  EXPECT_EQ(status, 1) << o;
  EXPECT_THAT(o, HasSubstr("no libssiu_tools.so"));
  EXPECT_EQ(std::count(o.begin(), o.end(), '\n'), 1) << o;
  status = testing::Run(none + testing::SsiuProgram() + " simulate gyro --help 2>&1", &o);
  EXPECT_EQ(status, 0) << o;
  std::ofstream(d + "/text.so") << "not a module\n";
  status =
      testing::Run("SSIU_TOOLS_MODULE=" + d + "/text.so " + testing::SsiuProgram() + " fog thermal x.csv 2>&1", &o);
  EXPECT_EQ(status, 2) << o;
  EXPECT_THAT(o, HasSubstr("cannot load " + d + "/text.so"));
}

}  // namespace
}  // namespace ssiu
