#include <cstdio>

#include "attitude/sim_campaign.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// The normal-run version (50 frames) of the 1000-frame acceptance run in sim_frames_longtest.cc.
TEST(SimulatedFrames, FiftyRandomFramesSolvedCorrectly) {
  const testing::CampaignStats st = testing::RunCampaign(50, 1);
  const double nees = testing::Median(st.nees);
  std::printf("solved %d/%d, wrong %d, median cross error at 16.6 deg %.2f arcsec (%zu frames), median NEES %.2f\n",
              st.solved, st.frames, st.wrong, testing::Median(st.cross_arcsec_166), st.cross_arcsec_166.size(), nees);
  EXPECT_GE(st.solved, 49);
  EXPECT_EQ(st.wrong, 0);
  EXPECT_LE(testing::Median(st.cross_arcsec_166), 1.0);
  // Median NEES of ~50 frames (the mean is at the mercy of single frames; the 1000-frame long test
  // checks the mean): chi-square(3) median 2.37, sampling sd ~0.35, 99% bounds about [1.47, 3.27].
  EXPECT_GT(nees, 1.47);
  EXPECT_LT(nees, 3.27);
}

}  // namespace
}  // namespace ssiu
