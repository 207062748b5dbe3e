// Turntable magnetic-sensitivity test against simulated 25-position logs with known trim error
// and magnetic sensitivities.
#include "calibration/fog_magnetic.h"

#include <Eigen/Dense>
#include <cmath>

#include "core/error.h"
#include "core/types.h"
#include "sim/fog_bench_sim.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TurntableData ToData(const TurntableLog& log, const std::string& name) {
  return TurntableData{name, log.t_s, log.wx_dph, log.wy_dph, log.azimuth_deg};
}

// What the test can identify, computed from the simulator's parameters: the harmonic matrix in
// the nominal azimuth psi is N = (W I + M_mag) R(dpsi0), with M_mag from the field seen along and
// across each axis; the identifiable trim is the rotation angle of N's conformal part, and the
// magnetic error is N - W R(trim).
struct Truth {
  double dpsi0_deg, amplitude_dph;
};
Truth IdentifiableTruth(const TurntableOptions& o) {
  const double w = kEarthRateDph * std::cos(o.latitude_deg * kDegToRad);
  const auto& x = o.fog_x;
  const auto& y = o.fog_y;
  Eigen::Matrix2d m;  // rows: FOGX, FOGY; columns: cos(psi'), sin(psi')
  m << w + x.along_dph_per_ut * o.bn_ut + x.across_dph_per_ut * o.be_ut,
      x.along_dph_per_ut * o.be_ut - x.across_dph_per_ut * o.bn_ut,
      -y.along_dph_per_ut * o.be_ut + y.across_dph_per_ut * o.bn_ut,
      w + y.along_dph_per_ut * o.bn_ut + y.across_dph_per_ut * o.be_ut;
  auto rot = [](double a) {
    Eigen::Matrix2d r;
    r << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
    return r;
  };
  const Eigen::Matrix2d n = m * rot(o.dpsi0_deg * kDegToRad);
  const double trim = std::atan2(0.5 * (n(1, 0) - n(0, 1)), 0.5 * (n(0, 0) + n(1, 1)));
  const Eigen::Matrix2d h = n - w * rot(trim);
  return {trim * kRadToDeg, std::max(h.row(0).norm(), h.row(1).norm())};
}

TEST(FogMagnetic, TrimOnlyGivesMeasureConsistentWithZero) {
  TurntableOptions o;
  o.dpsi0_deg = 0.5;
  const MagneticResult r = FitMagneticSensitivity(ToData(SimulateTurntable(o), "trim"), MagneticOptions{});
  EXPECT_EQ(r.dwells.size(), 25u);
  EXPECT_NEAR(r.dpsi0_deg, 0.5, 3 * r.dpsi0_sigma_deg);
  EXPECT_LT(r.dpsi0_sigma_deg, 0.05);
  EXPECT_TRUE(r.consistent_with_zero) << "chi2 " << r.magnetic_chi2;
  // The paper's criterion: a trim error alone gives S_x = -S_y.
  EXPECT_NEAR(r.x.s_dph, -r.y.s_dph, 3 * std::hypot(r.x.s_sigma_dph, r.y.s_sigma_dph));
  EXPECT_NEAR(r.x.dw_dph, o.bias_x_dph, 3 * r.x.dw_sigma_dph);
  EXPECT_NEAR(r.y.dw_dph, o.bias_y_dph, 3 * r.y.dw_sigma_dph);
}

TEST(FogMagnetic, RecoversTrimAndMagneticAmplitudeWithin3Sigma) {
  TurntableOptions o;
  o.dpsi0_deg = -0.8;
  o.fog_x = {0.006, 0.003, 0.002};
  o.fog_y = {-0.004, 0.005, -0.001};
  const Truth truth = IdentifiableTruth(o);
  ASSERT_GT(truth.amplitude_dph, 0.08);  // a field effect of the paper's order (+-0.15 deg/h)
  const MagneticResult r = FitMagneticSensitivity(ToData(SimulateTurntable(o), "mag"), MagneticOptions{});
  EXPECT_NEAR(r.dpsi0_deg, truth.dpsi0_deg, 3 * r.dpsi0_sigma_deg);
  EXPECT_NEAR(r.magnetic_amplitude_dph, truth.amplitude_dph, 3 * r.magnetic_amplitude_sigma_dph);
  EXPECT_FALSE(r.consistent_with_zero);
  EXPECT_GT(r.magnetic_measure_dph, 5 * r.magnetic_measure_sigma_dph);
}

// Calibration of the sigmas over many logs: z-scores of dpsi0 and amplitude, and the false-alarm
// rate of the zero test.
TEST(FogMagnetic, SigmasAreCalibratedOver20Logs) {
  int dpsi_in = 0, amp_in = 0, zero_ok = 0;
  for (int s = 0; s < 20; ++s) {
    TurntableOptions o;
    o.seed = 100 + s;
    o.dpsi0_deg = 0.3;
    const MagneticResult r0 = FitMagneticSensitivity(ToData(SimulateTurntable(o), "z"), MagneticOptions{});
    zero_ok += r0.consistent_with_zero;
    o.fog_x = {0.005, -0.002, 0.0};
    o.fog_y = {0.003, 0.004, 0.0};
    const Truth truth = IdentifiableTruth(o);
    const MagneticResult r = FitMagneticSensitivity(ToData(SimulateTurntable(o), "m"), MagneticOptions{});
    dpsi_in += std::abs(r.dpsi0_deg - truth.dpsi0_deg) <= 3 * r.dpsi0_sigma_deg;
    amp_in += std::abs(r.magnetic_amplitude_dph - truth.amplitude_dph) <= 3 * r.magnetic_amplitude_sigma_dph;
  }
  EXPECT_GE(dpsi_in, 19);
  EXPECT_GE(amp_in, 19);
  EXPECT_GE(zero_ok, 19);
}

TEST(FogMagnetic, TransientsAfterTurnsAreExcluded) {
  TurntableOptions o;
  o.transient_dph = 5.0;  // large, decays in ~15 s; settle_s = 60 s removes it
  o.transient_tau_s = 10;
  const MagneticResult r = FitMagneticSensitivity(ToData(SimulateTurntable(o), "tr"), MagneticOptions{});
  EXPECT_TRUE(r.consistent_with_zero) << r.magnetic_chi2;
  EXPECT_NEAR(r.dpsi0_deg, o.dpsi0_deg, 3 * r.dpsi0_sigma_deg);
}

TEST(FogMagnetic, BadInputIsInputError) {
  TurntableOptions o;
  o.positions = 3;
  EXPECT_THROW(FitMagneticSensitivity(ToData(SimulateTurntable(o), "few"), MagneticOptions{}), InputError);
  o.positions = 25;
  TurntableData d = ToData(SimulateTurntable(o), "bad");
  TurntableData nan_row = d;
  nan_row.wy_dph[100] = std::nan("");
  EXPECT_THROW(FitMagneticSensitivity(nan_row, MagneticOptions{}), InputError);
  std::swap(d.t_s[10], d.t_s[11]);
  EXPECT_THROW(FitMagneticSensitivity(d, MagneticOptions{}), InputError);
}

}  // namespace
}  // namespace ssiu
