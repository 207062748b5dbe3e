#include "inertial/fdi.h"

#include "core/error.h"
#include "core/rng.h"
#include "inertial/propagate.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// Four-FOG outputs with biases and white noise; a step on `fault_gyro` from t_fault.
TEST(Fdi, ParityDetectsStepOnEachGyroAndStaysQuietWithout) {
  const GyroUnit u = DefaultFourFogUnit();
  const double dt = 0.01, sigma = 0.01 * 60 / std::sqrt(dt);  // ARW 0.01 deg/sqrt(h)
  const GyroVec biases = (GyroVec(4) << 2.0, -3.0, 1.5, 2.5).finished();
  for (int fault_gyro = 0; fault_gyro <= 4; ++fault_gyro) {  // 0: no fault
    ParityMonitor m(u.Axes(), std::vector<bool>(4, true), GyroVec::Constant(4, sigma), dt, FdiOptions{});
    Rng rng(100 + fault_gyro);
    double t_alarm = -1;
    for (int k = 1; k <= 180000 && t_alarm < 0; ++k) {  // 30 min
      const double t = k * dt;
      GyroVec g = u.Axes() * Vec3(100 * std::sin(t / 50), 360, -20) + biases;
      for (int i = 0; i < 4; ++i) g[i] += sigma * rng.Normal();
      if (fault_gyro > 0 && t > 900) g[fault_gyro - 1] += 20.0;
      if (m.Feed(t, g)) t_alarm = t;
    }
    if (fault_gyro == 0) {
      EXPECT_LT(t_alarm, 0) << "false alarm";
    } else {
      EXPECT_GT(t_alarm, 900) << "gyro " << fault_gyro;
      EXPECT_LT(t_alarm, 960) << "gyro " << fault_gyro;
      // At the alarm the window is partly filled: the jump has the sign of 20 * V(gyro) and at
      // most its size.
      const double full = 20.0 * m.V()(0, fault_gyro - 1);
      EXPECT_GT(m.jump()[0] * full, 0.0);
      EXPECT_LT(std::abs(m.jump()[0]), std::abs(full) + 0.5);
    }
  }
}

TEST(Fdi, IsolationRules) {
  FdiOptions o;
  const std::vector<bool> all(4, true);
  EXPECT_EQ(IsolateFromResiduals((GyroVec(4) << 0.3, 19.5, -0.8, 0.5).finished(), all, o), 1);
  EXPECT_EQ(IsolateFromResiduals((GyroVec(4) << 0.3, 9.5, -8.0, 0.5).finished(), all, o), -1);  // ambiguous
  EXPECT_EQ(IsolateFromResiduals((GyroVec(4) << 0.3, 0.5, -0.2, 0.1).finished(), all, o), -1);  // too small
  // With five gyros the parity direction alone points at the failed one.
  GyroUnit u = DefaultFourFogUnit();
  u.axes_body.push_back(Vec3(1, -1, 0).normalized());
  u.gyros.push_back(GyroErrorModel{});
  const std::vector<bool> five(5, true);
  const GyroParity v = ParityMatrix(u.Axes(), five);
  // A gyro whose parity column is parallel to no other one is isolated; otherwise the answer is
  // "cannot tell" (-1), never a wrong gyro.
  int isolated = 0;
  for (int i = 0; i < 5; ++i) {
    bool unique = true;
    for (int j = 0; j < 5; ++j) {
      if (j != i && std::abs(v.col(i).normalized().dot(v.col(j).normalized())) >= o.parity_isolation_cos)
        unique = false;
    }
    const int got = IsolateFromParity(v, v.col(i) * 20.0, five, o);
    EXPECT_EQ(got, unique ? i : -1) << "gyro " << i;
    isolated += got == i;
  }
  EXPECT_GE(isolated, 3);
  // With one parity relation it cannot.
  const GyroParity v4 = ParityMatrix(DefaultFourFogUnit().Axes(), all);
  EXPECT_EQ(IsolateFromParity(v4, v4.col(0) * 20.0, all, o), -1);
}

TEST(Fdi, OptionsCheck) {
  FdiOptions o;
  o.window_s = 0;
  EXPECT_THROW(o.Check(), InputError);
  o = FdiOptions{};
  o.isolation_ratio = 0.5;
  EXPECT_THROW(o.Check(), InputError);
  o = FdiOptions{};
  o.baseline_margin_sigma = -1;
  EXPECT_THROW(o.Check(), InputError);
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

// Feeds four-FOG parity with white noise (6 deg/h per sample at 100 Hz) and `fault(t, i)` added to gyro i.
template <typename Fault>
double FirstAlarm(ParityMonitor* m, uint64_t seed, double t_end, Fault fault) {
  const GyroUnit u = DefaultFourFogUnit();
  Rng rng(seed);
  for (long k = 1;; ++k) {
    const double t = k * 0.01;
    if (t > t_end) return -1;
    GyroVec g = u.Axes() * Vec3(50, -20, 360) + (GyroVec(4) << 2.0, -3.0, 1.5, 2.5).finished();
    for (int i = 0; i < 4; ++i) g[i] += 6.0 * rng.Normal() + fault(t, i);
    if (m->Feed(t, g)) return t;
  }
}

// The CUSUM thresholds come from the target false-alarm rate (fdi.h). With a target high enough to
// measure (36 per hour) on fault-free noise the measured rate matches it within its Poisson spread and
// the approximation's error, so the threshold, not luck, sets it. (The default target is 1e-3 per hour.)
TEST(Fdi, CusumFalseAlarmRateIsBelowItsTarget) {
  const GyroUnit u = DefaultFourFogUnit();
  FdiOptions o;
  o.false_alarm_per_h = 36;
  o.warmup_s = 2;
  o.threshold_sigma = 50;  // the window test out of the way
  // The thresholds' own calibration, on a baseline taken as known (the 2 s warm-ups' baselines are far
  // off, and the default margin for that error would hide the thresholds behind it).
  o.baseline_margin_sigma = 0;
  const double hours = 1.0;
  double t_used = 0, m_h = 0;
  int alarms = 0;
  for (uint64_t seed = 1; t_used < hours * 3600; ++seed) {
    ParityMonitor m(u.Axes(), std::vector<bool>(4, true), GyroVec::Constant(4, 6.0), 0.01, o);
    const double t = FirstAlarm(&m, seed, hours * 3600 - t_used, [](double, int) { return 0.0; });
    m_h = m.cusum_threshold();
    if (t < 0) break;
    ++alarms;
    t_used += t - o.warmup_s;
  }
  const double rate_per_h = alarms / hours;
  std::printf("CUSUM false alarms: %d in %.1f h at a target of %.0f per hour (h = %.2f)\n", alarms, hours,
              o.false_alarm_per_h, m_h);
  EXPECT_LE(rate_per_h, 1.5 * o.false_alarm_per_h);
  EXPECT_GE(rate_per_h, o.false_alarm_per_h / 3);
  EXPECT_NEAR(CusumThreshold(9, 100.0, 1e-3), std::log(9 * 100.0 * 3600 / 1e-3), 1e-12);
}

// A slow ramp (1 deg/h per second) on each gyro: the CUSUM finds it within seconds, dates its onset
// and fits a ramp of the right slope on that gyro's parity column; a noise burst is told apart.
TEST(Fdi, CusumCatchesASlowRampAndANoiseBurst) {
  const GyroUnit u = DefaultFourFogUnit();
  FdiOptions o;
  o.threshold_sigma = 50;  // the CUSUM's own time: the window test (a second later at most) out of the way
  for (int gi = 0; gi < 4; ++gi) {
    ParityMonitor m(u.Axes(), std::vector<bool>(4, true), GyroVec::Constant(4, 6.0), 0.01, o);
    const double t =
        FirstAlarm(&m, 40 + gi, 400, [gi](double t, int i) { return i == gi && t > 100 ? (t - 100) : 0.0; });
    ASSERT_GT(t, 100) << gi;
    EXPECT_LT(t, 110) << gi;
    EXPECT_EQ(m.alarm_test(), "cusum");
    EXPECT_NEAR(m.onset_s(), 100, 5.0);  // the CUSUM's last zero: when the ramp began to tell
    // Tracked on (as while the fault is isolated) for 20 s, the fit since onset settles.
    Rng rng(90 + gi);
    for (double tt = t + 0.01; tt < t + 20; tt += 0.01) {
      GyroVec g = u.Axes() * Vec3(50, -20, 360) + (GyroVec(4) << 2.0, -3.0, 1.5, 2.5).finished();
      for (int i = 0; i < 4; ++i) g[i] += 6.0 * rng.Normal() + (i == gi ? tt - 100 : 0.0);
      m.Track(tt, g);
    }
    GyroVec a, b;
    m.FitSinceOnset(&a, &b, nullptr);
    const GyroVec d = m.V().col(gi);
    EXPECT_NEAR(d.dot(b) / d.squaredNorm(), 1.0, 0.15) << gi;  // deg/h per s
  }
  ParityMonitor m(u.Axes(), std::vector<bool>(4, true), GyroVec::Constant(4, 6.0), 0.01, FdiOptions{});
  Rng burst(7);
  const double t =
      FirstAlarm(&m, 50, 400, [&](double t, int i) { return i == 3 && t > 100 ? 40 * burst.Normal() : 0.0; });
  EXPECT_GT(t, 100);
  EXPECT_LT(t, 105);
  EXPECT_EQ(m.alarm_test(), "noise");
}

// FitFault against a known fault: three gyros (x, y and the skew one) on a constant body rate, gyro 4
// ramping 3 deg/h + 0.5 deg/h per s, star attitudes at 1 Hz with 5/5/30 arcsec noise, one 10 s outage
// (a second chain). At 60 s the fault is 33 deg/h and its slope 0.5: over 20 runs the errors divided
// by the reported sigma have an RMS near 1 (a sigma that is neither overconfident nor loose).
TEST(Fdi, StarRateFaultFitRecoversARampWithItsSigma) {
  const GyroAxes axes = DefaultFourFogUnit().Axes();
  const std::vector<bool> use = {true, true, false, true};
  const Vec3 w = Vec3(0.3, -0.5, 0.8).normalized() * (0.1 * kDegToRad);  // 0.1 deg/s slew
  const double dt = 0.1, sx = 5 * kArcsecToRad, sz = 30 * kArcsecToRad;
  const Mat3 r = Vec3(sx * sx, sx * sx, sz * sz).asDiagonal();
  double q_value = 0, q_ramp = 0, worst_sigma = 0;
  const int runs = 20;
  for (int run = 0; run < runs; ++run) {
    Rng rng(1600 + run);
    StarRateIsolator iso(axes, use, GyroVec::Zero(4));
    auto star = [&](double t) {
      Vec3 n;
      for (int a = 0; a < 3; ++a) n[a] = (a < 2 ? sx : sz) * rng.Normal();
      iso.AddStar(t, QuatFromRotationVector(w * t) * QuatFromRotationVector(n), r);
    };
    star(0);
    for (int k = 1; k <= 600; ++k) {
      const double t = k * dt, t_mid = t - dt / 2;
      GyroVec g = axes * (w * kRadSToDph);
      g[3] += 3 + 0.5 * t_mid;  // the mean of the ramp over the sample
      iso.AddGyro(g, dt);
      if (k % 10 != 0) continue;
      if (t > 20.5 && t < 30.5) {  // outage: the chain breaks
        iso.BreakChain();
        continue;
      }
      star(t);
    }
    const FaultFit f = iso.FitFault(3, 0, 60);
    ASSERT_GT(f.n, 40);
    q_value += std::pow((f.value_dph - 33) / f.sigma_dph, 2);
    q_ramp += std::pow(f.ramp_dph_per_s - 0.5, 2);
    worst_sigma = std::max(worst_sigma, f.sigma_dph);
    EXPECT_NEAR(f.value_dph, 33, 5 * f.sigma_dph) << "run " << run;
  }
  const double nrms = std::sqrt(q_value / runs), ramp_rms = std::sqrt(q_ramp / runs);
  std::printf("fault fit at 60 s: normalised value error RMS %.2f, sigma up to %.2f deg/h, ramp error RMS %.3f\n", nrms,
              worst_sigma, ramp_rms);
  EXPECT_GT(nrms, 0.6);
  EXPECT_LT(nrms, 1.5);
  EXPECT_LT(worst_sigma, 3.0);
  EXPECT_LT(ramp_rms, 0.1);
  // A gyro with no fault fits to zero; too few samples give no fit.
  StarRateIsolator quiet(axes, use, GyroVec::Zero(4));
  for (int k = 0; k <= 20; ++k) {
    if (k > 0) quiet.AddGyro(axes * (w * kRadSToDph), 1.0);
    quiet.AddStar(k, QuatFromRotationVector(w * k), r);
  }
  const FaultFit z = quiet.FitFault(0, 0, 20);
  EXPECT_NEAR(z.value_dph, 0, 1e-6);
  EXPECT_NEAR(z.ramp_dph_per_s, 0, 1e-6);
  EXPECT_EQ(quiet.FitFault(0, 18.5, 20).n, 0);
}

}  // namespace
}  // namespace ssiu
