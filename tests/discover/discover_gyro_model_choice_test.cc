// The stepwise extension's choice between the field harmonic and the misalignment (FieldPhaseWarranted, a
// Laplace approximation of a Bayes factor) against the evidences computed by numerical integration, and the
// ties it reports (StepRivals).
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

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

GyroCandidate Candidate(const std::string& cause, double statistic, double bic, const std::string& verdict = "") {
  GyroCandidate c;
  c.cause = cause, c.statistic = statistic, c.bic = bic, c.verdict = verdict, c.significant = true;
  return c;
}

// The misalignment and the field harmonic as rivals (StepRivals): the reported delta_bic is 2 ln B of the named
// one against the other, and the other is listed exactly where the integrated evidences put 2 ln B below 2
// (away from that boundary by more than the approximation's error).
TEST(DiscoverGyroModelChoice, FieldAndMisalignmentAreRivalsWhereTheEvidenceIsNearEven) {
  const double r = 30;
  int listed = 0, unlisted = 0;
  for (double snr : {5.0, 8.0, 12.0}) {
    for (double phase_deg : {5.0, 10.0, 12.0, 15.0, 18.0, 20.0, 25.0, 30.0, 40.0}) {
      const double s_hat = snr * std::cos(phase_deg * kDegToRad), c_hat = snr * std::sin(phase_deg * kDegToRad);
      const double two_ln_b = 2 * (LnEvidenceMisalignment(s_hat, c_hat, r) - LnEvidenceField(s_hat, c_hat, r));
      // The misalignment's chi^2 is its one coefficient's, the field's both: the extra chi^2 is c_hat^2.
      const std::vector<GyroCandidate> step = {Candidate("misalignment", s_hat * s_hat, 0),
                                               Candidate("magnetic_field", snr * snr, 0),
                                               Candidate("temperature", 50, 40, "held-out gain not significant")};
      for (const bool mis_named : {true, false}) {
        NamedCause nc;
        nc.candidate = step[mis_named ? 0 : 1];
        const std::vector<GyroRival> rivals = StepRivals(nc, step);
        const double two_ln_b_named = mis_named ? two_ln_b : -two_ln_b;  // 2 ln B(named : other)
        if (std::abs(two_ln_b_named - kBareMentionBic) < 0.5) continue;
        const bool expect = two_ln_b_named < kBareMentionBic;
        ASSERT_EQ(rivals.size(), expect ? 1u : 0u) << "SNR " << snr << " phase " << phase_deg << " named "
                                                   << nc.candidate.cause << " 2 ln B " << two_ln_b_named;
        (expect ? listed : unlisted)++;
        if (expect) {
          EXPECT_EQ(rivals[0].cause, mis_named ? "magnetic_field" : "misalignment");
          EXPECT_NEAR(rivals[0].delta_bic, two_ln_b_named, 0.5);
        }
      }
    }
  }
  EXPECT_GE(listed, 10);
  EXPECT_GE(unlisted, 10);
}

// The other rivals are the significant candidates whose BIC lies within 2 above the named one's (or below it),
// not those a gate refused; a walk or lag matched by the chain without it is one.
TEST(DiscoverGyroModelChoice, RivalsAreTheUnrefusedCandidatesWithinTwoOfTheNamedOnesBic) {
  GyroCandidate weak = Candidate("scale_factor", 3, 95);
  weak.significant = false;
  const std::vector<GyroCandidate> step = {
      Candidate("temperature", 60, 100, "named"),
      Candidate("bias_step", 55, 101.5),                                             // untried, 1.5 above: a rival
      Candidate("temperature_gradient", 58, 99.0, "held-out gain not significant"),  // refused
      Candidate("periodic_drift", 40, 102.5),                                        // 2.5 above: not a rival
      Candidate("rate_random_walk", 30, 100.7, kChainWithoutIt),                     // the chain without it kept
      Candidate("magnetic_field", 45, 98.0),                                         // below the named one's
      weak};
  NamedCause nc;
  nc.candidate = step[0];
  const std::vector<GyroRival> rivals = StepRivals(nc, step);
  ASSERT_EQ(rivals.size(), 3u);
  EXPECT_EQ(rivals[0].cause, "magnetic_field");
  EXPECT_DOUBLE_EQ(rivals[0].delta_bic, -2.0);
  EXPECT_EQ(rivals[1].cause, "rate_random_walk");
  EXPECT_NEAR(rivals[1].delta_bic, 0.7, 1e-12);
  EXPECT_EQ(rivals[2].cause, "bias_step");
  EXPECT_NEAR(rivals[2].delta_bic, 1.5, 1e-12);
  // A named cause its step did not find significant (its BIC was never computed) has none.
  nc.candidate = weak;
  EXPECT_TRUE(StepRivals(nc, step).empty());
}

}  // namespace
}  // namespace ssiu::discover_internal
