#include <cstdio>

#include "attitude/sim_campaign.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// The normal-run version (50 frames) of the 1000-frame acceptance run in sim_frames_longtest.cc.
TEST(SimulatedFrames, FiftyRandomFramesSolvedCorrectly) {
  const testing::CampaignStats st = testing::RunCampaign(50, 1);
  const double nees = st.nees_sum / st.nees_n;
  std::printf("solved %d/%d, wrong %d, median cross error at 16.6 deg %.2f arcsec (%zu frames), mean NEES %.2f\n",
              st.solved, st.frames, st.wrong, testing::Median(st.cross_arcsec_166), st.cross_arcsec_166.size(), nees);
  EXPECT_GE(st.solved, 49);
  EXPECT_EQ(st.wrong, 0);
  EXPECT_LE(testing::Median(st.cross_arcsec_166), 1.0);
  // Mean NEES over ~50 frames: chi-square(3n)/n, 99% bounds about [2.2, 3.9].
  EXPECT_GT(nees, 2.2);
  EXPECT_LT(nees, 3.9);
}

}  // namespace
}  // namespace ssiu
