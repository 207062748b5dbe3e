#include <algorithm>
#include <cmath>
#include <cstdio>

#include "attitude/sim_campaign.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

double P99(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, v.size() * 99 / 100)];
}

// Issue 4 acceptance: 1000 frames, >= 99.5% solved, none more than 1 arcmin off, median boresight
// error <= 1 arcsec at 16.6 deg, covariance consistent (mean NEES within its 95% bounds).
TEST(SimulatedFramesLong, ThousandRandomFrames) {
  const testing::CampaignStats st = testing::RunCampaign(1000, 100000);
  const double nees = st.nees_sum / st.nees_n;
  const double half = 1.96 * std::sqrt(6.0 / st.nees_n);
  std::printf(
      "solved %d/%d, wrong %d, median cross error at 16.6 deg %.3f arcsec (%zu frames), mean NEES %.3f "
      "(95%% bounds %.3f..%.3f), median identify %.3f ms, p99 %.3f ms (wall)\n",
      st.solved, st.frames, st.wrong, testing::Median(st.cross_arcsec_166), st.cross_arcsec_166.size(), nees, 3 - half,
      3 + half, testing::Median(st.solve_ms), P99(st.solve_ms));
  for (const auto& [fov, n] : st.unsolved_by_fov_deg) std::printf("unsolved at %d deg: %d\n", fov, n);
  EXPECT_GE(st.solved, 995);
  EXPECT_EQ(st.wrong, 0);
  EXPECT_LE(testing::Median(st.cross_arcsec_166), 1.0);
  EXPECT_GT(nees, 3 - half);
  EXPECT_LT(nees, 3 + half);
}

}  // namespace
}  // namespace ssiu
