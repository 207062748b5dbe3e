// The stepwise extension's choice between the field harmonic and the misalignment (FieldPhaseWarranted, a
// Laplace approximation of a Bayes factor) against the evidences computed by numerical integration.
#include <gtest/gtest.h>

#include <cmath>

#include "core/types.h"
#include "discover/discover_gyro_internal.h"

namespace ssiu::discover_internal {
namespace {

// ln of the evidence of each model for a harmonic estimated at (s_hat, c_hat) with unit Gaussian errors:
// misalignment: c = 0, s uniform on [-r, r]; field: amplitude uniform on [0, r], phase uniform.
double LnEvidenceMisalignment(double s_hat, double c_hat, double r) {
  const double ds = 0.01;
  double z = 0;  // over s_hat +- 9 (beyond, exp(-40) of the peak)
  for (double s = std::max(-r, s_hat - 9); s <= std::min(r, s_hat + 9); s += ds)
    z += std::exp(-0.5 * ((s_hat - s) * (s_hat - s) + c_hat * c_hat)) * ds;
  return std::log(z / (2 * kPi) / (2 * r));
}

double LnEvidenceField(double s_hat, double c_hat, double r) {
  const double da = 0.02, dphi = 5e-3, a_hat = std::hypot(s_hat, c_hat);
  double z = 0;  // over amplitudes a_hat +- 8 (beyond, exp(-32) of the peak)
  for (double a = std::max(da / 2, a_hat - 8); a < std::min(r, a_hat + 8); a += da) {
    for (double phi = dphi / 2; phi < 2 * kPi; phi += dphi) {
      const double ds = s_hat - a * std::cos(phi), dc = c_hat - a * std::sin(phi);
      z += std::exp(-0.5 * (ds * ds + dc * dc)) * da * dphi;
    }
  }
  return std::log(z / (2 * kPi) / (2 * kPi * r));
}

TEST(DiscoverGyroModelChoice, FieldPhaseFollowsTheIntegratedBayesFactor) {
  // Harmonics 5-12 sigma strong at phases 5-60 deg from the misalignment's; where the integrated evidences
  // differ by more than 0.25 in ln B (the approximation's error is of order 1/SNR^2), the closed form
  // must choose as they do.
  const double r = 30;
  int checked = 0;
  for (double snr : {5.0, 8.0, 12.0}) {
    for (double phase_deg : {5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0, 60.0}) {
      const double s_hat = snr * std::cos(phase_deg * kDegToRad), c_hat = snr * std::sin(phase_deg * kDegToRad);
      const double ln_b = LnEvidenceMisalignment(s_hat, c_hat, r) - LnEvidenceField(s_hat, c_hat, r);
      if (std::abs(ln_b) < 0.25) continue;
      ++checked;
      EXPECT_EQ(FieldPhaseWarranted(c_hat * c_hat, snr * snr), ln_b < 0)
          << "SNR " << snr << " phase " << phase_deg << " deg: ln B(misalignment : field) " << ln_b;
    }
  }
  EXPECT_GE(checked, 18);
  // A phase test at alpha = 0.01 (chi^2_1 > 6.63) keeps the misalignment where the evidence is the field's:
  // 8 sigma at 18 deg (extra chi^2 6.1).
  const double s_hat = 8 * std::cos(18 * kDegToRad), c_hat = 8 * std::sin(18 * kDegToRad);
  EXPECT_LT(LnEvidenceMisalignment(s_hat, c_hat, r) - LnEvidenceField(s_hat, c_hat, r), 0);
  EXPECT_TRUE(FieldPhaseWarranted(c_hat * c_hat, 64));
}

}  // namespace
}  // namespace ssiu::discover_internal
