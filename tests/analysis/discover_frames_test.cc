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
