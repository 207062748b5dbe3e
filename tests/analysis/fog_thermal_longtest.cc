// The acceptance Monte Carlo of the thermal term selection: 100 simulated two-run campaigns with
// random true subsets of the ten K_ij terms.
#include "fog_thermal_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(FogThermalLong, TermSelectionMonteCarlo100Cases) {
  const ThermalMcSummary s = RunThermalSelectionMc(100, 7000);
  std::cout << s.Describe() << "\n";
  EXPECT_GE(s.exact_selection, 90);
  EXPECT_GE(s.coefficients_within_3sigma_fraction, 0.98);
}

// The same campaigns selected without prewhitening (effective sample size only): the noise model
// must buy a better selection rate.
TEST(FogThermalLong, PrewhiteningBeatsWhiteNoiseBic) {
  ThermalFitOptions o;
  o.prewhiten = false;
  const ThermalMcSummary naive = RunThermalSelectionMc(100, 7000, o);
  const ThermalMcSummary gls = RunThermalSelectionMc(100, 7000);
  std::cout << "no prewhitening: " << naive.Describe() << "\n";
  EXPECT_LT(naive.exact_selection, gls.exact_selection);
}

}  // namespace
}  // namespace ssiu
