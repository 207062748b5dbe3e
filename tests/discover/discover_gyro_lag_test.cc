// `thermal_lag` of `discover gyro`: the lagged temperature against its closed form, and a few generated
// cases (seeds 9100-9101; the long test uses others) named thermal_lag with K and tau within 3 sigma.
#include "discover/discover_gyro_lag.h"

#include <cmath>

#include "discover_gyro_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// A ramp of G C/s from 20 C: the first-order lag settles to T - G tau (the ramp response,
// T_lag = 20 + G (t - tau (1 - exp(-t / tau)))); one bin per sample.
TEST(DiscoverGyroLag, LaggedTemperatureFollowsTheRampResponse) {
  std::vector<double> t, temp, y;
  std::vector<int> bin;
  const double g = 0.2 / 60, tau = 900;
  for (int k = 0; k <= 7200; ++k) {
    t.push_back(k);
    temp.push_back(20 + g * k);
    bin.push_back(k);
    y.push_back(0);
  }
  const LagLog log{&t, &temp, &bin, static_cast<int>(t.size()), &y};
  const std::vector<double> z = LaggedTemperatureBins(log, tau);
  for (int k : {0, 300, 900, 3600, 7200}) {
    const double lag = 20 + g * (k - tau * (1 - std::exp(-k / tau)));
    EXPECT_NEAR(z[k], (lag - 20) / 10, 1e-5) << k;
  }
}

// The scan finds the time constant of a noiseless lagged drift on a thermal cycle.
TEST(DiscoverGyroLag, ScanRecoversTheTimeConstant) {
  std::vector<double> t, temp, y0;
  std::vector<int> bin;
  for (int k = 0; k < 4320; ++k) {
    t.push_back(10.0 * k);
    temp.push_back(20 + 3 * std::sin(2 * kPi * t.back() / 5400));
    bin.push_back(k / 6);  // 1-minute bins
  }
  const int nb = 720;
  y0.assign(nb, 0);
  const LagLog probe{&t, &temp, &bin, nb, &y0};
  const std::vector<double> truth = LaggedTemperatureBins(probe, 1500);
  std::vector<double> y(nb);
  for (int b = 0; b < nb; ++b) y[b] = 0.2 * truth[b] + 0.7;  // K = 0.2 deg/h per 10 C, a bias
  const LagLog log{&t, &temp, &bin, nb, &y};
  const ThermalLagScan scan = ScanThermalLag({log}, 60, 6 * 3600);
  ASSERT_TRUE(scan.ok);
  EXPECT_NEAR(scan.tau_s, 1500, 15);
  EXPECT_GT(scan.positions, 3);
}

TEST(DiscoverGyroLag, ThermalCyclingCasesNameThermalLag) {
  if (testing::kUnderSanitizer)
    GTEST_SKIP() << "two whole thermal-cycling discoveries (too long for the sanitizer run's share of CI time); the "
                    "lag's scan, chain and "
                    "report run there in DiscoverGyroCli.ThermalLagInJsonAndSummary";
  int checked = 0, within = 0;
  std::string params;
  for (uint64_t seed : {9100u, 9101u}) {
    const testing::GyroCase c = testing::MakeGyroCase("thermal_lag", seed);
    const GyroDiscovery d = DiscoverGyro(c.logs, GyroDiscoverOptions{});
    EXPECT_EQ(d.cause, "thermal_lag") << "seed " << seed;
    if (d.cause != "thermal_lag") continue;
    testing::CheckParameters("", c.truth, d.parameters, d.sigmas, &checked, &within, &params);
  }
  EXPECT_EQ(within, checked) << params;
}

}  // namespace
}  // namespace ssiu
