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

// The same campaigns with the corrections switched off: a white-noise BIC (no prewhitening, no
// effective sample size) must do clearly worse, so the acceptance figures above depend on them.
// The prewhitening-only and n_eff-only variants are printed for docs/fog-calibration.md.
TEST(FogThermalLong, CorrelatedNoiseCorrectionsAreNeeded) {
  ThermalFitOptions naive_opts;
  naive_opts.prewhiten = false;
  naive_opts.effective_sample_size = false;
  const ThermalMcSummary naive = RunThermalSelectionMc(100, 7000, naive_opts);
  std::cout << "white-noise BIC: " << naive.Describe() << "\n";
  ThermalFitOptions neff_only;
  neff_only.prewhiten = false;
  std::cout << "n_eff only: " << RunThermalSelectionMc(100, 7000, neff_only).Describe() << "\n";
  ThermalFitOptions gls_only;
  gls_only.effective_sample_size = false;
  std::cout << "prewhitening only: " << RunThermalSelectionMc(100, 7000, gls_only).Describe() << "\n";
  EXPECT_LT(naive.exact_selection, 80);
  EXPECT_LT(naive.coefficients_within_3sigma_fraction, 0.95);
}

}  // namespace
}  // namespace ssiu
