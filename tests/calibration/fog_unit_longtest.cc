// The unit bench calibration's acceptance (issue: the four-FOG unit calibrated as a whole): 20
// simulated campaigns at the unit's 100 Hz (seeds 1-20; the normal suite uses 201-205 at 10 Hz).
#include <algorithm>
#include <cstdio>
#include <vector>

#include "fog_unit_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(FogUnitLong, TwentyCampaigns) {
  constexpr int kSeeds = 20;
  UnitCalScore s;
  std::vector<double> ratios;
  double nominal2 = 0, calibrated2 = 0;
  for (uint64_t seed = 1; seed <= kSeeds; ++seed) {
    const UnitCampaign c = MakeUnitCampaign(seed, 100);
    ScoreUnitCampaign(c, &s);
    const double nominal = OutageErrorArcsec(c.truth, c.nominal, seed, SlewAxisForSeed(seed));
    const double calibrated = OutageErrorArcsec(c.truth, c.fit.unit, seed, SlewAxisForSeed(seed));
    nominal2 += nominal * nominal, calibrated2 += calibrated * calibrated;
    ratios.push_back(nominal / calibrated);
    std::printf("seed %2d: outage error nominal %7.1f arcsec, calibrated %6.1f arcsec (x%.1f)\n",
                static_cast<int>(seed), nominal, calibrated, nominal / calibrated);
  }
  std::sort(ratios.begin(), ratios.end());
  const int at_least_5 = static_cast<int>(std::count_if(ratios.begin(), ratios.end(), [](double r) { return r >= 5; }));
  std::printf(
      "%s\nRMS outage error nominal %.1f arcsec, calibrated %.1f arcsec; ratio min %.1f median %.1f, >= 5 in %d/%d\n",
      s.Describe().c_str(), std::sqrt(nominal2 / kSeeds), std::sqrt(calibrated2 / kSeeds), ratios.front(),
      ratios[kSeeds / 2], at_least_5, kSeeds);
  EXPECT_GE(s.Fraction(), 0.95) << s.Describe();
  // 80 gyros x 4 dof: the mean NEES has a standard deviation of sqrt(8/80) = 0.32; 3 of them either side.
  EXPECT_GT(s.MeanNees(), 4 - 3 * 0.32) << s.Describe();
  EXPECT_LT(s.MeanNees(), 4 + 3 * 0.32) << s.Describe();
  EXPECT_GT(std::sqrt(nominal2), 5 * std::sqrt(calibrated2));
  EXPECT_GE(at_least_5, kSeeds * 9 / 10);
}

}  // namespace
}  // namespace ssiu
