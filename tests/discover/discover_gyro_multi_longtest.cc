// Acceptance of the stepwise extension of `ssiu discover gyro` (issue 31): logs with two hidden causes
// together, every pair of six causes (temperature, temperature_gradient, magnetic_field, bias_step,
// periodic_drift, scale_factor) drawn twice (30 cases; docs/discrepancy.md records the figures).
#include "discover_gyro_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(DiscoverGyroMultiLong, TwoCausesTogether) {
  const auto pairs = testing::GyroCausePairs(
      {"temperature", "temperature_gradient", "magnetic_field", "bias_step", "periodic_drift", "scale_factor"});
  const auto s = testing::RunGyroMultiMonteCarlo(pairs, 2, 626262, true);
  std::cout << "both named " << s.all_named << "/" << s.cases << ", a wrong cause " << s.wrong << ", unexplained "
            << s.unexplained << ", parameters within 3 sigma " << s.params_within_3_sigma << "/" << s.params_checked
            << "\n";
  for (const auto& [combo, rc] : s.per_combo) std::cout << "  " << combo << " " << rc.first << "/" << rc.second << "\n";
  EXPECT_GE(s.all_named, 0.9 * s.cases);
  EXPECT_LE(s.wrong, 0.05 * s.cases);
  EXPECT_GE(s.params_within_3_sigma, 0.9 * s.params_checked);
}

}  // namespace
}  // namespace ssiu
