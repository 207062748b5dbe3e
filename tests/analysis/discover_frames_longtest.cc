// Acceptance of `ssiu discover frames` (issue 7): 35 simulated frame sets of 4 frames, each with one
// hidden camera effect (distortion, focal length, principal point, vignetting, persistent hot
// pixels, PSF width) or none; the right cause in >= 90 %, `none` never confused with the transient
// hot pixels and cosmic rays, the fitted camera reduces residuals, held-out gain of the others > 1.
#include "discover_frames_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(DiscoverFramesLong, ThirtyFiveFrameSetsAcceptance) {
  const auto s = testing::RunFrameMonteCarlo(35, 4, 31337, true);
  std::cout << "right cause " << s.right << "/" << s.sets << ", geometric fits reducing residuals "
            << s.geometric_reduced << "/" << s.geometric_named << ", parameters within 3 sigma " << s.params_3sigma
            << "/" << s.params << ", none " << s.none_right << "/" << s.none_sets << ", hot_pixels/psf_shape gain > 1 "
            << s.other_gain << "/" << s.other_named << ", persistent pixels found " << s.hot_found << "/"
            << s.hot_detectable << " (> 1000 ADU), false " << s.hot_false << "\n";
  EXPECT_GE(s.right, 0.9 * s.sets);
  EXPECT_EQ(s.geometric_reduced, s.geometric_named);
  EXPECT_GE(s.none_right, 0.9 * s.none_sets);
  EXPECT_EQ(s.other_gain, s.other_named);
  EXPECT_GE(s.hot_found, 0.8 * s.hot_detectable);
}

// False alarms: 20 more sets with nothing hidden (transient hot pixels and cosmic rays only).
TEST(DiscoverFramesLong, TwentyCleanSetsStayNone) {
  const auto s = testing::RunFrameMonteCarlo(20, 4, 4242, true, {"none"});
  std::cout << "clean sets named none: " << s.none_right << "/" << s.none_sets << "\n";
  EXPECT_GE(s.none_right, 19);
}

}  // namespace
}  // namespace ssiu
