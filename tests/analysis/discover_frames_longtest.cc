// Acceptance of `ssiu discover frames` (issue 7): 30 simulated frame sets of 4 frames, each with one
// hidden camera effect or none; the right cause in >= 90 % and the fitted camera reduces residuals.
#include "discover_frames_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(DiscoverFramesLong, ThirtyFrameSetsAcceptance) {
  const auto s = testing::RunFrameMonteCarlo(30, 4, 31337, true);
  std::cout << "right cause " << s.right << "/" << s.sets << ", geometric fits reducing residuals "
            << s.geometric_reduced << "/" << s.geometric_named << ", parameters within 3 sigma " << s.params_3sigma
            << "/" << s.params << "\n";
  EXPECT_GE(s.right, 0.9 * s.sets);
  EXPECT_EQ(s.geometric_reduced, s.geometric_named);
}

}  // namespace
}  // namespace ssiu
