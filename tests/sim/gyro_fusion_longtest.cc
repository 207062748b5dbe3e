// 50-run Monte Carlo of the one-hour slew (issue 5 acceptance; label `long`, not in CI):
// bias error after 30 min, attitude RMS against the star-tracker noise, and NEES within its 95%
// bounds over the runs.
#include <cmath>
#include <cstdio>

#include "sim/gyro_fusion_scenario.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(GyroFusionMonteCarlo, FiftyOneHourSlews) {
  constexpr int kRuns = 50;
  double bias_sum2[3] = {0, 0, 0};
  int within = 0;
  double att_worst[3] = {0, 0, 0};
  // NEES of the 6-state error at t = 1800 s and 3600 s, summed over runs: chi^2 with 6 kRuns dof.
  double nees_1800 = 0, nees_3600 = 0;
  for (int r = 0; r < kRuns; ++r) {
    testing::FusionScenario sc;
    sc.seed = 1000 + r;
    const auto s = testing::RunFusionScenario(sc, 1800.0);
    ASSERT_EQ(s.fused.status, "fused");
    const size_t k30 = static_cast<size_t>(1800 * sc.rate_hz) - 1;
    for (int a = 0; a < 3; ++a) {
      const double e = s.fused.samples[k30].bias_dph[a] - s.sim.body_bias_dph[k30][a];
      bias_sum2[a] += e * e;
      att_worst[a] = std::max(att_worst[a], s.att_rms_arcsec[a]);
    }
    if (s.bias_err_max_dph < 0.02) ++within;
    nees_1800 += s.nees[k30];
    nees_3600 += s.nees.back();
  }
  const double n = kRuns;
  std::printf("bias RMS error at 30 min: %.4f %.4f %.4f deg/h; runs with all axes within 0.02: %d/%d\n",
              std::sqrt(bias_sum2[0] / n), std::sqrt(bias_sum2[1] / n), std::sqrt(bias_sum2[2] / n), within, kRuns);
  std::printf("worst attitude RMS: %.2f %.2f %.2f arcsec; mean NEES at 1800 s %.2f, at 3600 s %.2f\n", att_worst[0],
              att_worst[1], att_worst[2], nees_1800 / n, nees_3600 / n);
  for (int a = 0; a < 3; ++a) EXPECT_LT(std::sqrt(bias_sum2[a] / n), 0.02) << "axis " << a;
  EXPECT_LT(att_worst[0], 5.0);
  EXPECT_LT(att_worst[1], 5.0);
  EXPECT_LT(att_worst[2], 30.0);
  // 95% two-sided bounds of the mean of 50 chi^2(6) variables: chi^2(300) / 50 in [5.09, 7.00].
  EXPECT_GT(nees_1800 / n, 5.09);
  EXPECT_LT(nees_1800 / n, 7.00);
  EXPECT_GT(nees_3600 / n, 5.09);
  EXPECT_LT(nees_3600 / n, 7.00);
}

}  // namespace
}  // namespace ssiu
