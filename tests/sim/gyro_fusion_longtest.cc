// 50-run Monte Carlo of the one-hour slew (issue 5 acceptance; label `long`, not in CI):
// bias error after 30 min, attitude RMS against the star-tracker noise, and NEES within its 95%
// bounds over the runs.
#include <Eigen/Dense>
#include <cmath>
#include <cstdio>

#include "sim/gyro_fusion_scenario.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

struct McSummary {
  double bias_rms[3] = {0, 0, 0};
  int within = 0;
  double att_worst[3] = {0, 0, 0};
  double nees_1800 = 0, nees_3600 = 0;  // mean over runs
};

McSummary RunMonteCarlo(double bias_instability_dph) {
  constexpr int kRuns = 50;
  McSummary m;
  double bias_sum2[3] = {0, 0, 0};
  int within = 0;
  double att_worst[3] = {0, 0, 0};
  // NEES of the 6-state error at t = 1800 s and 3600 s, summed over runs: chi^2 with 6 kRuns dof.
  double nees_1800 = 0, nees_3600 = 0;
  for (int r = 0; r < kRuns; ++r) {
    testing::FusionScenario sc;
    sc.seed = 1000 + r;
    sc.bias_instability_dph = bias_instability_dph;
    const auto s = testing::RunFusionScenario(sc, 1800.0);
    EXPECT_EQ(s.fused.status, FuseStatus::kFused) << "seed " << sc.seed;
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
  for (int a = 0; a < 3; ++a) {
    m.bias_rms[a] = std::sqrt(bias_sum2[a] / n);
    m.att_worst[a] = att_worst[a];
  }
  m.within = within;
  m.nees_1800 = nees_1800 / n;
  m.nees_3600 = nees_3600 / n;
  std::printf("BI %.3f deg/h: bias RMS error at 30 min %.4f %.4f %.4f deg/h; runs with all axes within 0.02: %d/%d\n",
              bias_instability_dph, m.bias_rms[0], m.bias_rms[1], m.bias_rms[2], within, kRuns);
  std::printf("  worst attitude RMS %.2f %.2f %.2f arcsec; mean NEES at 1800 s %.2f, at 3600 s %.2f\n", att_worst[0],
              att_worst[1], att_worst[2], m.nees_1800, m.nees_3600);
  return m;
}

void ExpectConsistentAndBelowStarNoise(const McSummary& m) {
  EXPECT_LT(m.att_worst[0], 5.0);
  EXPECT_LT(m.att_worst[1], 5.0);
  EXPECT_LT(m.att_worst[2], 30.0);
  // 95% two-sided bounds of the mean of 50 chi^2(6) variables: chi^2(300) / 50 in [5.09, 7.00].
  EXPECT_GT(m.nees_1800, 5.09);
  EXPECT_LT(m.nees_1800, 7.00);
  EXPECT_GT(m.nees_3600, 5.09);
  EXPECT_LT(m.nees_3600, 7.00);
}

// Turn-on biases + angle random walk: the 0.02 deg/h after 30 min, as an RMS over 50 runs.
// No estimator can do better than the Cramer-Rao bound of a constant rate in white rate noise seen
// for T with the attitude known exactly at every instant: sigma_b = ARW_body / sqrt(T), where
// ARW_body^2 = ARW^2 diag((H'H)^-1) for the unit's axes H (least squares over the four gyros). At
// ARW 0.01 deg/sqrt(h) and T = 0.5 h that is 0.0129 deg/h per axis, so a single run has all three axes
// within 0.02 deg/h only about 68% of the time (|z| < 1.55 per axis) whatever the filter; the test
// checks that the MEKF reaches the bound (efficiency) and the RMS meets 0.02.
TEST(GyroFusionMonteCarlo, FiftyOneHourSlewsTurnOnBiasAndArw) {
  const McSummary m = RunMonteCarlo(0.0);
  const GyroUnit u = testing::ScenarioUnit(100, 0.0);
  Eigen::MatrixXd h(u.size(), 3);
  for (int i = 0; i < u.size(); ++i) h.row(i) = u.axes_body[i].transpose();
  const Eigen::Matrix3d hth_inv = (h.transpose() * h).inverse();
  const double t_h = 0.5;
  for (int a = 0; a < 3; ++a) {
    const double crb_dph = u.gyros[0].arw_deg_per_sqrt_h * std::sqrt(hth_inv(a, a) / t_h);
    std::printf("axis %d: bias RMS %.4f deg/h, Cramer-Rao bound %.4f deg/h, ratio %.2f\n", a, m.bias_rms[a], crb_dph,
                m.bias_rms[a] / crb_dph);
    EXPECT_LT(m.bias_rms[a], 0.02) << "axis " << a;
    // 50 runs: the RMS itself scatters by about 1 / sqrt(2 * 50) = 10%.
    EXPECT_GT(m.bias_rms[a], 0.75 * crb_dph) << "axis " << a;
    EXPECT_LT(m.bias_rms[a], 1.3 * crb_dph) << "axis " << a;
  }
  ExpectConsistentAndBelowStarNoise(m);
}

// With 0.05 deg/h flicker the bias wanders and its estimate is limited to about
// sqrt(ARW density * bias drift density) (docs/inertial.md); consistency and attitude still hold.
TEST(GyroFusionMonteCarlo, FiftyOneHourSlewsWithFlicker) {
  const McSummary m = RunMonteCarlo(0.05);
  ExpectConsistentAndBelowStarNoise(m);
}

}  // namespace
}  // namespace ssiu
