// `thermal_lag` (issue: thermal lag named): generated logs whose drift follows the logged temperature
// through a first-order lag of 5-60 min, in a thermal-cycling test and in the ramps of the other cases,
// and the eq. (1) causes and the periodic drift it must not take (label `long`).
#include "discover_gyro_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

void Print(const char* what, const testing::GyroMcSummary& s) {
  std::cout << what << ": found";
  for (const auto& [cause, n] : s.found) std::cout << " " << cause << " " << n;
  std::cout << "; parameters within 3 sigma " << s.params_within_3_sigma << "/" << s.params_checked << "\n";
}

int Found(const testing::GyroMcSummary& s, const std::string& cause) {
  return s.found.count(cause) ? s.found.at(cause) : 0;
}

TEST(DiscoverGyroLagLong, LaggedDriftIsThermalLagOrUnexplained) {
  const auto s = testing::RunGyroMonteCarlo({"thermal_lag"}, 20, 313131, true);
  Print("thermal cycling, lag 5-60 min", s);
  const int right = Found(s, "thermal_lag") + Found(s, "unexplained");
  const int wrong = s.cases - right - Found(s, "none");
  EXPECT_GE(right, 0.9 * s.cases);
  EXPECT_LE(wrong, 0.05 * s.cases);
  const auto r = testing::RunGyroMonteCarlo({"thermal_lag_ramp"}, 10, 323232, true);
  Print("ramps, lag 5-60 min", r);
  // On slow ramps a short lag is the temperature itself: no other cause may be named.
  EXPECT_EQ(Found(r, "thermal_lag") + Found(r, "unexplained") + Found(r, "temperature") + Found(r, "none"), r.cases);
}

TEST(DiscoverGyroLagLong, TemperatureCausesAndPeriodicDriftKeepTheirNames) {
  const auto s =
      testing::RunGyroMonteCarlo({"temperature", "temperature_gradient", "periodic_drift"}, 10, 333333, true);
  Print("temperature, temperature_gradient, periodic_drift", s);
  testing::PrintGyroRates(s);
  EXPECT_LE(Found(s, "thermal_lag"), 0.05 * s.cases);
}

}  // namespace
}  // namespace ssiu
