#include "analysis/discover_frames.h"
#include "core/error.h"
#include "discover_frames_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// Small version of the 30-set acceptance (discover_frames_longtest.cc): one set per cause.
TEST(DiscoverFrames, FiveHiddenCameraEffects) {
  const auto s = testing::RunFrameMonteCarlo(5, 3, 2024, true);
  EXPECT_GE(s.right, 4) << "right cause in " << s.right << " of " << s.sets;
  EXPECT_EQ(s.geometric_reduced, s.geometric_named);
}

TEST(DiscoverFrames, OptionsCheckRejectsBadValues) {
  FrameDiscoverOptions o;
  o.alpha = 0;
  EXPECT_THROW(o.Check(), InputError);
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

TEST(DiscoverFramesCli, BadInputExitsOne) {
  const std::string dir = testing::TempDir("discover_frames_bad");
  std::string out;
  EXPECT_EQ(testing::Run(testing::SsiuProgram() + " discover frames " + dir + "/missing.png --camera " + dir +
                             "/missing_camera.json",
                         &out),
            1)
      << out;
  EXPECT_THAT(out, ::testing::HasSubstr("missing_camera.json"));
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

// The real openstartracker frames (docs/discrepancy.md): the pinhole camera from the published
// 15.777 arcsec/px scale is off in focal length; fitting it cuts the held-out residuals.
TEST(DiscoverFramesReal, OpenStarTrackerFocalLength) {
  SSIU_REQUIRE_SHARED(dark_path, "openstartracker/median_image.png");
  Camera cam;
  cam.width = 1392, cam.height = 1040;
  cam.focal_length_px = 13073.9;
  cam.cx_px = 695.5, cam.cy_px = 519.5;
  SolveOptions so;
  so.identify.fov_tolerance_pct = 1.0;
  const StarIdentifier id = MakeIdentifierForCamera("", cam, so.identify.fov_tolerance_pct);
  const Frame dark = ReadFrame(dark_path);
  std::vector<Frame> frames;
  std::vector<std::string> names;
  for (int i = 0; i < 10; ++i) {
    SSIU_REQUIRE_SHARED(path, "openstartracker/img" + std::to_string(i) + ".png");
    frames.push_back(SubtractDark(ReadFrame(path), dark));
    names.push_back(path);
  }
  std::vector<ImageView> views;
  for (const auto& f : frames) views.push_back(f.image.view());
  so.detect.saturation_adu = frames.front().saturation_adu;
  const SolvedFrameSet set = SolveFrameSet(id, views, names, cam, so);
  const FrameDiscovery d = DiscoverFrames(set, cam, {});
  EXPECT_GE(d.frames_solved, 7);
  EXPECT_EQ(d.cause, "focal_length");
  EXPECT_GT(d.gain, 3.0);
  EXPECT_NEAR(d.parameters.at("focal_length_ppm"), 3300, 300);
  std::printf("openstartracker: %d/%d solved, %d stars, f %+.0f ppm, held-out rms %.2f -> %.2f arcsec\n",
              d.frames_solved, d.frames, d.stars, d.parameters.at("focal_length_ppm"), d.residual_rms_before_arcsec,
              d.residual_rms_after_arcsec);
}

}  // namespace
}  // namespace ssiu
