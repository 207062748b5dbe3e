// Acceptance of the star-inertial fusion on simulated four-FOG data (issue 5): bias estimate,
// attitude accuracy, consistency, outage bridging, fault detection and isolation. Small versions
// (a few runs, 10-20 Hz gyros); the 50-run Monte Carlo at 100 Hz is gyro_fusion_longtest.cc.
#include <cstdio>

#include "sim/gyro_fusion_scenario.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using testing::FusionScenario;
using testing::RunFusionScenario;

size_t IndexAt(const FuseResult& r, double t_s) {
  size_t k = 0;
  while (k + 1 < r.samples.size() && r.samples[k + 1].t_s <= t_s + 1e-9) ++k;
  return k;
}

// Turn-on biases of a few deg/h and ARW 0.01 deg/sqrt(h): the bias after 30 min is limited by the
// angle random walk to about 0.6 deg/h sqrt(s) / sqrt(1800 s) = 0.014 deg/h (1 sigma).
TEST(GyroFusion, OneHourSlewBiasWithinTwoHundredthsDegPerHour) {
  double sum2 = 0, nees_sum = 0;
  int n = 0, n_nees = 0;
  for (uint64_t seed : {21, 22, 23, 24, 25, 26}) {
    FusionScenario sc;
    sc.rate_hz = 10;
    sc.seed = seed;
    sc.bias_instability_dph = 0;
    const auto s = RunFusionScenario(sc, 1800.0);
    ASSERT_EQ(s.fused.status, FuseStatus::kFused);
    const size_t k30 = IndexAt(s.fused, 1800.0);
    for (int a = 0; a < 3; ++a) {
      const double e = s.fused.samples[k30].bias_dph[a] - s.sim.body_bias_dph[k30][a];
      sum2 += e * e;
      ++n;
    }
    nees_sum += s.nees[k30] + s.nees.back();
    n_nees += 2;
    EXPECT_LT(s.att_rms_arcsec[0], 5.0);
    EXPECT_LT(s.att_rms_arcsec[1], 5.0);
    EXPECT_LT(s.att_rms_arcsec[2], 30.0);
    EXPECT_TRUE(s.fused.faults.empty()) << "false alarm, seed " << seed;
    EXPECT_EQ(s.fused.n_st_rejected, 0);
  }
  const double rms = std::sqrt(sum2 / n);
  std::printf("bias RMS error at 30 min over 6 runs: %.4f deg/h; mean NEES %.2f\n", rms, nees_sum / n_nees);
  EXPECT_LT(rms, 0.02);
  // Twelve chi^2(6) samples: their sum is chi^2(72), 95% bounds [50.4, 97.4].
  ASSERT_EQ(n_nees, 12);
  EXPECT_GT(nees_sum, 50.4);
  EXPECT_LT(nees_sum, 97.4);
}

// With the default flicker (0.05 deg/h as Gauss-Markov processes) the bias wanders: the filter must
// track it consistently (bias NEES over runs within its 99% bounds) and keep the attitude below the
// star-tracker noise.
TEST(GyroFusion, FlickerBiasTrackedConsistently) {
  double nees = 0;
  int dof = 0;
  for (uint64_t seed : {31, 32, 33, 34}) {
    FusionScenario sc;
    sc.rate_hz = 20;
    sc.seed = seed;
    const auto s = RunFusionScenario(sc, 1800.0);
    for (double t : {1800.0, 3600.0}) {
      const size_t k = IndexAt(s.fused, t);
      for (int a = 0; a < 3; ++a) {
        const double e =
            (s.fused.samples[k].bias_dph[a] - s.sim.body_bias_dph[k][a]) / s.fused.samples[k].bias_sigma_dph[a];
        nees += e * e;
        ++dof;
      }
    }
    EXPECT_LT(s.att_rms_arcsec[0], 5.0);
    EXPECT_LT(s.att_rms_arcsec[1], 5.0);
    EXPECT_LT(s.att_rms_arcsec[2], 30.0);
  }
  std::printf("flicker bias NEES %.1f over %d dof\n", nees, dof);
  ASSERT_EQ(dof, 24);
  EXPECT_GT(nees, 9.89);   // chi^2(24) 0.5% quantile
  EXPECT_LT(nees, 45.56);  // 99.5% quantile
}

TEST(GyroFusion, TenMinuteOutageEndsWithinThreeSigma) {
  for (uint64_t seed : {41, 42}) {
    FusionScenario sc;
    sc.rate_hz = 20;
    sc.duration_s = 2700;
    sc.seed = seed;
    sc.outages_s = {{1800.5, 2400.5}};  // samples 1801..2400 missing
    const auto s = RunFusionScenario(sc, 1800.0);
    EXPECT_NEAR(s.fused.longest_st_gap_s, 601.0, 1e-6);
    const size_t k_before = IndexAt(s.fused, 1800.0);
    const size_t k_end = IndexAt(s.fused, 2400.0 - 1e-3);  // last propagated sample before the next fix
    for (int a = 0; a < 3; ++a) {
      const double err = std::abs(s.att_err_rad[k_end][a]);
      EXPECT_LT(err, 3 * s.fused.samples[k_end].sigma_rad[a]) << "seed " << seed << " axis " << a;
      EXPECT_GT(s.fused.samples[k_end].sigma_rad[a], s.fused.samples[k_before].sigma_rad[a]);
    }
    std::printf("outage end: error %.1f %.1f %.1f arcsec, sigma %.1f %.1f %.1f arcsec\n",
                s.att_err_rad[k_end][0] * kRadToArcsec, s.att_err_rad[k_end][1] * kRadToArcsec,
                s.att_err_rad[k_end][2] * kRadToArcsec, s.fused.samples[k_end].sigma_rad[0] * kRadToArcsec,
                s.fused.samples[k_end].sigma_rad[1] * kRadToArcsec, s.fused.samples[k_end].sigma_rad[2] * kRadToArcsec);
  }
}

std::string FaultsText(const FuseResult& r);

class GyroFaultTest : public ::testing::TestWithParam<int> {};

TEST_P(GyroFaultTest, StepOfTwentyDegPerHourDetectedIsolatedAndSolutionContinues) {
  const int gyro = GetParam();
  FusionScenario sc;
  sc.rate_hz = 20;
  sc.duration_s = 1500;
  sc.seed = 50 + gyro;
  sc.faults = {GyroFault{gyro, 600.0, 20.0, 0.0}};
  const auto s = RunFusionScenario(sc, 1500.0);
  ASSERT_EQ(s.fused.faults.size(), 1u);
  const FaultEvent& f = s.fused.faults[0];
  std::printf("gyro %d: detected at %.2f s, isolated at %.2f s (%s), fault %.2f deg/h\n", gyro, f.t_detect_s,
              f.t_isolate_s, f.method.c_str(), f.fault_dph);
  EXPECT_GE(f.t_detect_s, 600.0);
  EXPECT_LE(f.t_detect_s, 660.0);
  EXPECT_EQ(f.status, FaultStatus::kIsolated);
  EXPECT_EQ(f.gyro, gyro);
  EXPECT_NEAR(f.fault_dph, 20.0, 3.0);
  std::vector<int> expected;
  for (int i = 1; i <= 4; ++i) {
    if (i != gyro) expected.push_back(i);
  }
  EXPECT_EQ(s.fused.gyros_in_use, expected);
  // Through the transient (detection to a minute after isolation) the filter knows what it does not
  // know: the attitude error stays within its reported 3 sigma (the covariance opens at detection)
  // and the star tracker keeps it close, instead of the NIS gate refusing the fixes. (Between onset
  // and detection, 1-2 s here, nothing can know.)
  // Fraction of output samples in [t0, t1) with some axis outside 3 sigma.
  auto fraction_outside = [&](double t0, double t1) {
    long n = 0, out = 0;
    for (size_t k = IndexAt(s.fused, t0), end = IndexAt(s.fused, t1); k < end; ++k, ++n) {
      bool o = false;
      for (int a = 0; a < 3; ++a) o |= std::abs(s.att_err_rad[k][a]) > 3 * s.fused.samples[k].sigma_rad[a];
      out += o;
    }
    return n > 0 ? static_cast<double>(out) / n : 1.0;
  };
  double max_cross_arcsec = 0;
  // (90 s from detection: the span up to a minute after the 30 s star-rate isolation of old; it is
  // decided sequentially now, within 6-9 s.)
  for (size_t k = IndexAt(s.fused, f.t_detect_s), end = IndexAt(s.fused, f.t_detect_s + 90); k < end; ++k) {
    if (s.fused.samples[k].t_s > f.t_detect_s + 1.5)
      max_cross_arcsec =
          std::max(max_cross_arcsec, std::hypot(s.att_err_rad[k][0], s.att_err_rad[k][1]) * kRadToArcsec);
  }
  const double transient = fraction_outside(f.t_detect_s, f.t_detect_s + 90);
  // The same measure on the fault-free stretch of this run (the fault comes at 600 s): its worst
  // 90 s window.
  double nominal = 0;
  for (double t0 = 60; t0 + 90 <= 600; t0 += 10) nominal = std::max(nominal, fraction_outside(t0, t0 + 90));
  std::printf(
      "transient: %.1f%% of samples outside 3 sigma (fault-free 90 s windows: up to %.1f%%), max cross error %.1f "
      "arcsec after the first fix, %ld fixes rejected\n",
      100 * transient, 100 * nominal, max_cross_arcsec, s.fused.n_st_rejected);
  // Before the covariance opened at detection, 9-16% of these samples were outside and fixes were
  // refused. Now at most 5%, or no more than the fault-free filter of the same run shows over 90 s:
  // the roll error (30 arcsec star roll noise, a star-fix gain of about 8%) is correlated over tens
  // of seconds, so one 90 s window of a consistent filter may hold a 5 s excursion. Gyro 3's run
  // has one 53-58 s after isolation (5.6%; roll 21-35 arcsec at 8.5-9 arcsec sigma, moving only at
  // the star fixes, 4-6 arcsec each); its fault-free stretch has windows up to 8.9% outside, and its
  // normalised roll error RMS over the 300 s after isolation is 0.95 (x 1.09, y 0.96): consistent, not
  // a covariance closed too early (docs/results.md).
  EXPECT_LE(transient, std::max(0.05, nominal));
  EXPECT_EQ(s.fused.n_st_rejected, 0);
  // A 20 deg/h step moves the attitude 5.6 arcsec/s: unchecked over the 6-10 s to isolation that is
  // 35-56 arcsec. Measured: 16-19 arcsec (GCC), 27 arcsec (clang, gyro 4 isolated 2 s later).
  EXPECT_LT(max_cross_arcsec, 40.0);
  // The solution continues on three gyros: attitude after isolation within star-tracker noise, and
  // the bias settles back to the three-gyro truth... (truth includes the faulty gyro's step, so only
  // the attitude is scored).
  double sum2[3] = {0, 0, 0};
  long n = 0;
  for (size_t k = IndexAt(s.fused, f.t_isolate_s + 60); k < s.fused.samples.size(); ++k, ++n) {
    for (int a = 0; a < 3; ++a) sum2[a] += s.att_err_rad[k][a] * s.att_err_rad[k][a];
  }
  ASSERT_GT(n, 0);
  EXPECT_LT(std::sqrt(sum2[0] / n) * kRadToArcsec, 5.0);
  EXPECT_LT(std::sqrt(sum2[1] / n) * kRadToArcsec, 5.0);
  EXPECT_LT(std::sqrt(sum2[2] / n) * kRadToArcsec, 30.0);
}

INSTANTIATE_TEST_SUITE_P(EachGyro, GyroFaultTest, ::testing::Values(1, 2, 3, 4));

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

// Five gyros have two parity relations: the parity direction alone isolates the failed gyro, at
// detection time, on a sinusoidal motion.
TEST(GyroFusion, FiveGyroUnitIsolatesByParityOnSineMotion) {
  GyroUnit u = DefaultFourFogUnit();
  u.rate_hz = 20;
  u.axes_body.push_back(Vec3(1, -1, 0.5).normalized());
  u.gyros.push_back(GyroErrorModel{});
  for (int i = 0; i < 5; ++i) u.gyros[i].bias_dph = 1.0 + 0.5 * i;
  MotionProfile p = MotionProfileFromJson(Json{{"type", "sine"}, {"period_s", 120.0}}, "mem");
  p.faults = {GyroFault{1, 400.0, 20.0, 0.0}};
  GyroSimOptions o;
  o.duration_s = 900;
  o.seed = 61;
  const GyroSimulation sim = SimulateGyro(u, p, o);
  GyroLog log;
  log.t_s = sim.t_s;
  log.rates_dph = sim.gyro_dph;
  StarTrackerLog st;
  st.t_s = sim.st_t_s;
  st.q_inertial_from_body = sim.st_q;
  const FuseResult r = Fuse(log, st, u, FuseOptions{});
  std::printf("%s\n", FaultsText(r).c_str());
  ASSERT_EQ(r.faults.size(), 1u);
  EXPECT_EQ(r.faults[0].method, "parity");
  EXPECT_EQ(r.faults[0].gyro, 1);
  EXPECT_GT(r.faults[0].t_detect_s, 400.0);
  EXPECT_LT(r.faults[0].t_detect_s, 460.0);
  EXPECT_EQ(r.faults[0].t_isolate_s, r.faults[0].t_detect_s);
  EXPECT_EQ(r.gyros_in_use, (std::vector<int>{2, 3, 4, 5}));
  // After isolation the attitude stays within the star-tracker noise.
  double sum2 = 0;
  long n = 0;
  for (size_t k = 0; k < r.samples.size(); ++k) {
    if (r.samples[k].t_s < 520) continue;
    const Vec3 e = RotationVectorFromQuat(sim.q_true[k].conjugate() * r.samples[k].q_inertial_from_body);
    sum2 += e.head<2>().squaredNorm() / 2;
    ++n;
  }
  EXPECT_LT(std::sqrt(sum2 / n) * kRadToArcsec, 5.0);
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

std::string FaultsText(const FuseResult& r) {
  std::string out;
  char b[256];
  for (const auto& f : r.faults) {
    std::snprintf(b, sizeof b, "[%s gyro %d %s onset %.1f detect %.1f isolate %.1f %s step %.1f ramp %.2f size %.1f] ",
                  FaultStatusName(f.status), f.gyro, f.test.c_str(), f.t_onset_s, f.t_detect_s, f.t_isolate_s,
                  f.shape.c_str(), f.step_dph, f.ramp_dph_per_s, f.fault_dph);
    out += b;
  }
  return out;
}

// Issue 16's case, on a gyro + star log: gyro 2 drifting 10 deg/h per second from t = 100 s (it was
// 4,016 arcsec off at 1.7-2.1 arcsec sigma, status ok), then, after its isolation, a step of 50 deg/h
// on gyro 4, which parity can no longer see (three gyros): the star innovations detect it, the star
// rates name it. Throughout, the attitude is within 3 reported sigma or the status is not ok.
TEST(GyroFusion, RampThenSecondFaultStayTrustworthy) {
  FusionScenario sc;
  sc.rate_hz = 20;
  sc.duration_s = 400;
  sc.seed = 16;
  GyroFault ramp{2, 100.0, 0.0, 36000.0};
  GyroFault step{4, 250.0, 50.0, 0.0};
  sc.faults = {ramp, step};
  const auto s = RunFusionScenario(sc, 400.0);
  double bad_s = 0;
  const double frac = TrustworthyFraction(s, 10.0, &bad_s);
  std::printf("ramp + step: %.2f%% trustworthy (%.1f s ok but outside 3 sigma), status %s, %s\n", 100 * frac, bad_s,
              FuseStatusName(s.fused.status), FaultsText(s.fused).c_str());
  EXPECT_GE(frac, 0.99);
  ASSERT_EQ(s.fused.faults.size(), 2u);
  EXPECT_EQ(s.fused.faults[0].gyro, 2);
  EXPECT_EQ(s.fused.faults[0].status, FaultStatus::kIsolated);
  EXPECT_EQ(s.fused.faults[0].shape, "ramp");
  EXPECT_NEAR(s.fused.faults[0].ramp_dph_per_s, 10.0, 1.5);
  EXPECT_LT(s.fused.faults[0].t_detect_s, 105.0);
  EXPECT_GT(s.fused.faults[1].t_detect_s, 250.0);
  EXPECT_LT(s.fused.faults[1].t_detect_s, 280.0);
  EXPECT_EQ(s.fused.faults[1].test, "star_innovation");
  EXPECT_NE(s.fused.status, FuseStatus::kFused);
}

// Two faults in a row, the second a slow ramp with no parity left: gyro 2 steps 20 deg/h at 100 s
// and is isolated; gyro 4 then ramps 0.5 deg/h per s from 300 s. The star rates must follow the ramp
// as one fault (before: a new "isolated" event of ~10 deg/h every 30 s, 6-18 of them, each a
// constant compensation, and the rest absorbed by the bias, 94-171 deg/h on body y at the end).
TEST(GyroFusion, StepThenSlowRampOnThreeGyrosIsOneTrackedFault) {
  FusionScenario sc;
  sc.rate_hz = 20;
  sc.duration_s = 900;
  sc.seed = 1617;
  sc.faults = {GyroFault{2, 100.0, 20.0, 0.0}, GyroFault{4, 300.0, 0.0, 0.5 * 3600}};
  const auto s = RunFusionScenario(sc, 900.0);
  double bad_s = 0;
  const double frac = TrustworthyFraction(s, 10.0, &bad_s);
  const Vec3 b = s.fused.samples.back().bias_dph;
  std::printf(
      "step + slow ramp: %.2f%% trustworthy (%.1f s ok but outside 3 sigma), status %s, bias %.2f %.2f %.2f "
      "deg/h, %s\n",
      100 * frac, bad_s, FuseStatusName(s.fused.status), b[0], b[1], b[2], FaultsText(s.fused).c_str());
  EXPECT_GE(frac, 0.99);
  ASSERT_EQ(s.fused.faults.size(), 2u);
  EXPECT_EQ(s.fused.faults[0].gyro, 2);
  const FaultEvent& f = s.fused.faults[1];
  EXPECT_EQ(f.gyro, 4);
  EXPECT_EQ(f.status, FaultStatus::kIsolated);
  EXPECT_EQ(f.test, "star_innovation");
  EXPECT_EQ(f.shape, "ramp");
  EXPECT_NEAR(f.ramp_dph_per_s, 0.5, 0.05);
  EXPECT_GE(f.t_onset_s, 290.0);
  EXPECT_LE(f.t_onset_s, f.t_detect_s);
  EXPECT_GT(f.t_detect_s, 300.0);
  EXPECT_LT(f.t_detect_s, 330.0);
  // At 900 s the ramp is 300 deg/h; compensated, the body bias stays at the unit's few deg/h.
  EXPECT_LT(b.norm(), 5.0);
  // Once gyro 2 is isolated no spare is left (policy.degraded_without_spare): never "ok" again, so the
  // seconds before the ramp is detected are not reported as trustworthy either.
  const double t_first = s.fused.faults[0].t_isolate_s;
  long ok_after = 0;
  for (const FusedSample& fs : s.fused.samples) ok_after += fs.t_s >= t_first && fs.status == FusionStatus::kOk;
  EXPECT_EQ(ok_after, 0);
  EXPECT_NE(s.fused.status, FuseStatus::kFused);
}

TEST(GyroFusion, NoSpareGyroLeftIsDegradedUnlessThePolicySaysOtherwise) {
  // One 100 deg/h step, isolated within seconds; three gyros remain.
  FusionScenario sc;
  sc.rate_hz = 20;
  sc.duration_s = 200;
  sc.seed = 1618;
  sc.faults = {GyroFault{3, 60.0, 100.0, 0.0}};
  for (bool policy : {true, false}) {
    sc.policy.degraded_without_spare = policy;
    const auto s = RunFusionScenario(sc, 200.0);
    ASSERT_EQ(s.fused.faults.size(), 1u);
    const double t_iso = s.fused.faults[0].t_isolate_s;
    ASSERT_LT(t_iso, 80.0);
    long ok_before = 0, ok_late = 0, late = 0;
    for (const FusedSample& fs : s.fused.samples) {
      ok_before += fs.t_s > 10 && fs.t_s < 59 && fs.status == FusionStatus::kOk;
      if (fs.t_s > t_iso + 20) {  // past the settling time after isolation
        ++late;
        ok_late += fs.status == FusionStatus::kOk;
      }
    }
    EXPECT_GT(ok_before, 900) << policy;  // ok with four gyros
    EXPECT_EQ(ok_late, policy ? 0 : late) << policy;
  }
}

}  // namespace
}  // namespace ssiu
