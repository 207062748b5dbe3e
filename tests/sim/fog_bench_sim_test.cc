// The simulated bench campaigns have the design the calibration relies on.
#include "sim/fog_bench_sim.h"

#include <cmath>

#include "core/error.h"
#include "core/types.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(FogBenchSim, ThermalCampaignSpansTheProgrammeAndDriftBand) {
  ThermalBenchOptions o;
  o.drift = CampaignDriftModel();
  double tmin = 1e9, tmax = -1e9, gmax = 0, dmax = 0;
  for (uint64_t seed : {1, 2}) {
    o.seed = seed;
    const ThermalBenchRun sim = SimulateThermalRun(o);
    EXPECT_EQ(sim.t_s.size(), 42001u);
    for (size_t i = 0; i < sim.t_s.size(); ++i) {
      tmin = std::min(tmin, sim.true_temp_c[i]);
      tmax = std::max(tmax, sim.true_temp_c[i]);
      gmax = std::max(gmax, std::abs(sim.true_rate_c_per_min[i]));
      dmax = std::max(dmax, std::abs(sim.true_drift_dph[i]));
    }
  }
  EXPECT_LT(tmin, 21.5);
  EXPECT_GT(tmax, 28.5);
  EXPECT_GT(gmax, 0.2);
  EXPECT_LE(gmax, 0.25 + 1e-9);
  EXPECT_GT(dmax, 0.8);
  EXPECT_LT(dmax, 1.3);
}

TEST(FogBenchSim, ThermalRateIsTheDerivativeOfTemperature) {
  ThermalBenchOptions o;
  o.temp_noise_c = 0;
  const ThermalBenchRun sim = SimulateThermalRun(o);
  for (size_t i = 1000; i + 1 < sim.t_s.size(); i += 1000) {
    const double fd = (sim.true_temp_c[i + 1] - sim.true_temp_c[i - 1]) / 2.0 * 60.0;
    EXPECT_NEAR(sim.true_rate_c_per_min[i], fd, 2e-3) << i;
  }
}

TEST(FogBenchSim, TurntableNoiseFreeOutputIsTheEarthRateProjection) {
  TurntableOptions o;
  o.white_noise_dph = o.wander_sigma_dph = o.transient_dph = 0;
  o.bias_x_dph = o.bias_y_dph = 0;
  const TurntableLog log = SimulateTurntable(o);
  const double w = kEarthRateDph * std::cos(o.latitude_deg * kDegToRad);
  EXPECT_DOUBLE_EQ(log.azimuth_deg.back(), 360.0);
  for (size_t i = 0; i < log.t_s.size(); i += 777) {
    const double psi = (log.azimuth_deg[i] + o.dpsi0_deg) * kDegToRad;
    EXPECT_NEAR(log.wx_dph[i], w * std::cos(psi), 1e-9);
    EXPECT_NEAR(log.wy_dph[i], w * std::sin(psi), 1e-9);
  }
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

// Absurd sizes are bad input, not hours of simulation (1e12 s, 1e8 azimuths); a latitude past the
// pole or a NaN trim error is refused rather than written out as NaN rates.
TEST(FogBenchSim, AbsurdOptionsAreInputErrors) {
  ThermalBenchOptions t;
  t.duration_s = 1e12;
  EXPECT_THROW(t.Check(), InputError);
  TurntableOptions o;
  o.positions = 100000000;
  EXPECT_THROW(o.Check(), InputError);
  o = TurntableOptions{};
  o.latitude_deg = 95;
  EXPECT_THROW(o.Check(), InputError);
  o.latitude_deg = std::nan("");
  EXPECT_THROW(o.Check(), InputError);
  o = TurntableOptions{};
  o.dpsi0_deg = std::nan("");
  EXPECT_THROW(o.Check(), InputError);
  EXPECT_NO_THROW(TurntableOptions{}.Check());
  EXPECT_NO_THROW(ThermalBenchOptions{}.Check());
}

}  // namespace
}  // namespace ssiu
