// `ssiu solve --fov-range-deg MIN,MAX` end to end (issue 14 item 3): a camera.json with width and
// height only, centroid lists simulated with cameras of 10-19 deg; the reported focal length
// against the simulator's, the attitude against its truth, and the usage errors.
#include <cmath>
#include <fstream>

#include "core/attitude.h"
#include "core/catalog.h"
#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using Result = testing::SsiuResult;
Result Ssiu(const std::string& args) { return testing::RunSsiu(args); }

class FovRangeCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(testing::TempDir("fov_range_cli"));
    std::ofstream(Path("nofocal.json")) << R"({"width": 1024, "height": 768})";
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string Path(const std::string& n) { return *dir_ + "/" + n; }
  // The solver flags shared by the cases: the 8-25 deg catalog is built in DIR/cat by the first
  // solve (BSC source: quicker than the KStars default for 8 deg, enough for these frames).
  static std::string Common() { return " --catalog " + Path("cat") + " --source " + DefaultBscPath(); }
  static std::string* dir_;
};
std::string* FovRangeCli::dir_ = nullptr;

TEST_F(FovRangeCli, FindsTheFocalLengthOfFramesItWasNotTold) {
  const double fovs[] = {10.5, 14.0, 19.0};
  for (int k = 0; k < 3; ++k) {
    const std::string d = Path("sim" + std::to_string(k));
    const double f_true = 512.0 / std::tan(0.5 * fovs[k] * kDegToRad);
    std::ofstream(Path("cam.json")) << "{\"width\": 1024, \"height\": 768, \"focal_length_px\": " << f_true << "}";
    ASSERT_EQ(Ssiu("simulate frame --camera " + Path("cam.json") + " --random --seed " + std::to_string(40 + k) +
                   " --centroids-only --scene-csv --false-objects 3 --out " + d)
                  .status,
              0);
    const Result r = Ssiu("solve --centroids " + d + "/frame_0000_centroids.csv --camera " + Path("nofocal.json") +
                          " --fov-range-deg 8,25 --json " + Path("s.json") + Common() +
                          " --timeout-ms 0");  // the hypothesis budget, not the clock: ASan runs 5-10x slower
    ASSERT_EQ(r.status, 0) << r.output;
    const Json s = ReadJsonFile(Path("s.json"));
    ASSERT_EQ(s["status"], "solved") << fovs[k] << " deg: " << s["message"];
    const double f = s["focal_length_px"].get<double>();
    EXPECT_NEAR(f / f_true, 1.0, 0.002) << fovs[k] << " deg";
    const Json truth = ReadJsonFile(d + "/frame_0000.json");
    const Quat qt = FromWxyz(truth["q"][0], truth["q"][1], truth["q"][2], truth["q"][3]);
    const Quat qs = FromWxyz(s["q"][0], s["q"][1], s["q"][2], s["q"][3]);
    EXPECT_LT(SplitAttitudeError(qs, qt).cross_rad * kRadToArcsec, 60.0) << fovs[k] << " deg";
    EXPECT_LT(s["false_match_probability"].get<double>(), 1e-5);
  }
}

TEST_F(FovRangeCli, NoFocalLengthWithoutTheFlagIsAOneLineError) {
  std::ofstream(Path("c.csv")) << "x_px,y_px\n1,2\n3,4\n5,6\n7,8\n";
  const Result r = Ssiu("solve --centroids " + Path("c.csv") + " --camera " + Path("nofocal.json") + Common());
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.output, ::testing::HasSubstr("nofocal.json: missing field 'focal_length_px'"));
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
}

TEST_F(FovRangeCli, BadRangesAreUsageErrors) {
  std::ofstream(Path("c.csv")) << "x_px,y_px\n1,2\n3,4\n5,6\n7,8\n";
  const std::string base = "solve --centroids " + Path("c.csv") + " --camera " + Path("nofocal.json");
  for (const char* bad : {"25,8", "0.1,8", "8", "8,95"}) {
    const Result r = Ssiu(base + " --fov-range-deg " + bad + Common());
    EXPECT_EQ(r.status, 1) << bad;
    EXPECT_THAT(r.output, ::testing::HasSubstr("--fov-range-deg")) << bad;
  }
  const Result both = Ssiu(base + " --fov-range-deg 8,25 --fov-tolerance-pct 5" + Common());
  EXPECT_EQ(both.status, 1);
  EXPECT_THAT(both.output, ::testing::HasSubstr("not both"));
  // fy without fx in an unknown-FOV camera.json names the field.
  std::ofstream(Path("fy.json")) << R"({"width": 1024, "height": 768, "focal_length_y_px": 3000})";
  const Result fy =
      Ssiu("solve --centroids " + Path("c.csv") + " --camera " + Path("fy.json") + " --fov-range-deg 8,25" + Common());
  EXPECT_EQ(fy.status, 1);
  EXPECT_THAT(fy.output, ::testing::HasSubstr("focal_length_y_px"));
}

// A catalog built for another range is refused, naming both (the issue 16 integrity rule).
TEST_F(FovRangeCli, CatalogOfAnotherRangeIsRefused) {
  ASSERT_EQ(
      Ssiu("catalog build --fov-deg 25 --fov-min-deg 8 --source " + DefaultBscPath() + " --out " + Path("cat2")).status,
      0);
  std::ofstream(Path("c.csv")) << "x_px,y_px\n1,2\n3,4\n5,6\n7,8\n";
  const Result r = Ssiu("solve --centroids " + Path("c.csv") + " --camera " + Path("nofocal.json") +
                        " --fov-range-deg 4,25 --catalog " + Path("cat2"));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.output, ::testing::HasSubstr("8.00-25.00 deg"));
  EXPECT_THAT(r.output, ::testing::HasSubstr("4.00-25.00 deg"));
}

}  // namespace
}  // namespace ssiu
