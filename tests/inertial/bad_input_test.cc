// Bad inputs to the estimator core and the unit processor (issue 26 item 6): every one gives a status
// that says what happened, nothing throws, and the attitude stays finite and right against the truth
// of a closed-form run (analytic_fusion.h).
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#include "core/camera.h"
#include "inertial/online_fusion.h"
#include "inertial/unit_processor.h"
#include "inertial/analytic_fusion.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using testing::AnalyticFusion;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// Runs `duration_s` of gyro samples (100 Hz) and star fixes (1 Hz, the first at t = 0); `edit` may
// change each gyro sample (k: its index from 1) and the status of each AddGyro call is checked by
// `check`. Returns the final attitude error (arcsec).
template <typename Edit, typename Check>
double RunAnalytic(AnalyticFusion* sim, OnlineFusion* f, double duration_s, Edit edit, Check check) {
  Mat3 r;
  const Quat q = sim->Star(0.0, &r);
  f->AddAttitude(0.0, q, r);
  const long n = std::lround(duration_s / sim->dt_s);
  for (long k = 1; k <= n; ++k) {
    const double t = k * sim->dt_s;
    GyroVec g = sim->Gyro(t);
    double t_tag = t;
    edit(k, &t_tag, &g);
    check(k, f->AddGyro(t_tag, g));
    EXPECT_TRUE(f->q().coeffs().allFinite()) << "t " << t;
    if (k % 100 == 0) {
      const Quat qs = sim->Star(t, &r);
      f->AddAttitude(t, qs, r);
    }
  }
  return sim->ErrorRad(f->q(), n * sim->dt_s) * kRadToArcsec;
}

// The estimate agrees with the truth within 3 (n_sigma) of its own covariance on every body axis.
void ExpectWithin3Sigma(const OnlineFusion& f, const AnalyticFusion& sim, double t_s, double n_sigma = 3) {
  const Vec3 e = RotationVectorFromQuat(sim.Truth(t_s).conjugate() * f.q());
  const Vec3 sigma = f.attitude_sigma_rad();
  for (int a = 0; a < 3; ++a) {
    EXPECT_LT(std::abs(e[a]), n_sigma * sigma[a]) << "axis " << a << ": " << e[a] * kRadToArcsec << " arcsec, sigma "
                                             << sigma[a] * kRadToArcsec;
  }
}

auto NoEdit = [](long, double*, GyroVec*) {};
auto AllAccepted = [](long k, GyroSampleStatus s) { EXPECT_EQ(s, GyroSampleStatus::kAccepted) << k; };

// One sample with a NaN (inf, or an absurd value) in one of the four outputs in the middle of a
// 120 s run: the sample is used with the rate of the other three, the call says so, and the attitude
// at the end is what the same run without the bad value gives (over one 10 ms step the 3-gyro rate
// differs from the 4-gyro one by a share of one sample's noise, 6 deg/h, and of the biases: under
// 0.1 arcsec then, and the fixes that follow pull it in further; measured 0.0001 arcsec).
TEST(BadInput, OneBadOutputCostsNothing) {
  AnalyticFusion clean_sim;
  OnlineFusion clean(clean_sim.unit, FuseOptions{});
  const double e_clean = RunAnalytic(&clean_sim, &clean, 120, NoEdit, AllAccepted);
  ExpectWithin3Sigma(clean, clean_sim, 120);
  for (double bad : {kNaN, kInf, -kInf, 1e12}) {
    AnalyticFusion sim;
    OnlineFusion f(sim.unit, FuseOptions{});
    const long k_bad = 6000;
    const double e = RunAnalytic(
        &sim, &f, 120,
        [&](long k, double*, GyroVec* g) {
          if (k == k_bad) (*g)[1] = bad;
        },
        [&](long k, GyroSampleStatus s) {
          EXPECT_EQ(s, k == k_bad ? GyroSampleStatus::kAcceptedPartial : GyroSampleStatus::kAccepted) << k;
        });
    EXPECT_NEAR(e, e_clean, 0.01) << bad;
    std::printf("output %g at 60 s: final error %.4f arcsec, %.4f without it\n", bad, e, e_clean);
    EXPECT_EQ(f.n_gyro_status(GyroSampleStatus::kAcceptedPartial), 1);
    EXPECT_EQ(f.n_outputs_non_finite(), std::isfinite(bad) ? 0 : 1);
    EXPECT_EQ(f.n_outputs_out_of_range(), std::isfinite(bad) ? 1 : 0);
    EXPECT_EQ(f.Status(), FusionStatus::kOk);
    EXPECT_TRUE(f.faults().empty());  // the parity monitor never saw the made-up output
  }
}

// Every output NaN: no rate from the sample, the last one is held over its interval; the run ends
// where the clean one does (one 10 ms step on a constant rate). A 3-gyro unit has no spare: one NaN
// output is the same case.
TEST(BadInput, SampleWithoutARateHoldsTheLastRate) {
  AnalyticFusion clean_sim;
  OnlineFusion clean(clean_sim.unit, FuseOptions{});
  const double e_clean = RunAnalytic(&clean_sim, &clean, 60, NoEdit, AllAccepted);
  AnalyticFusion sim;
  OnlineFusion f(sim.unit, FuseOptions{});
  const double e = RunAnalytic(
      &sim, &f, 60,
      [](long k, double*, GyroVec* g) {
        if (k == 3000) g->setConstant(kNaN);
      },
      [](long k, GyroSampleStatus s) {
        EXPECT_EQ(s, k == 3000 ? GyroSampleStatus::kRejectedNonFinite : GyroSampleStatus::kAccepted) << k;
      });
  EXPECT_NEAR(e, e_clean, 0.05);
  EXPECT_EQ(f.n_outputs_non_finite(), 4);
  EXPECT_DOUBLE_EQ(f.t_s(), 60.0);

  AnalyticFusion triad_sim;
  triad_sim.unit = OrthogonalTriad();
  triad_sim.axes = triad_sim.unit.Axes();
  triad_sim.bias_dph.conservativeResize(3);
  triad_sim.sigma_dph.conservativeResize(3);
  OnlineFusion triad(triad_sim.unit, FuseOptions{});
  RunAnalytic(
      &triad_sim, &triad, 60,
      [](long k, double*, GyroVec* g) {
        if (k == 3000) (*g)[2] = kNaN;
      },
      [](long k, GyroSampleStatus s) {
        EXPECT_EQ(s, k == 3000 ? GyroSampleStatus::kRejectedNonFinite : GyroSampleStatus::kAccepted) << k;
      });
  ExpectWithin3Sigma(triad, triad_sim, 60);
}

// A gyro that outputs NaN for 20 s: the unit runs on the other three (status degraded meanwhile: no
// redundancy, no parity), and is ok again once the gyro is back.
TEST(BadInput, AGyroSilentForSecondsLeavesThreeToRunOn) {
  AnalyticFusion sim;
  OnlineFusion f(sim.unit, FuseOptions{});
  int degraded = 0;
  RunAnalytic(
      &sim, &f, 120,
      [](long k, double*, GyroVec* g) {
        if (k > 4000 && k <= 6000) (*g)[3] = kNaN;
      },
      [&](long k, GyroSampleStatus s) {
        const bool bad = k > 4000 && k <= 6000;
        EXPECT_EQ(s, bad ? GyroSampleStatus::kAcceptedPartial : GyroSampleStatus::kAccepted) << k;
        degraded += f.Status() == FusionStatus::kDegraded;
      });
  ExpectWithin3Sigma(f, sim, 120);
  EXPECT_EQ(degraded, 2000);
  EXPECT_EQ(f.Status(), FusionStatus::kOk);
}

// Time going backwards, repeated, not a number, and a sample of the wrong size: refused, and the
// state is exactly what it was.
TEST(BadInput, RefusedSamplesLeaveTheStateUnchanged) {
  AnalyticFusion sim;
  OnlineFusion f(sim.unit, FuseOptions{});
  RunAnalytic(&sim, &f, 10, NoEdit, AllAccepted);
  const Quat q = f.q();
  const Mat6 p = f.P();
  const Vec3 b = f.bias_rad_s();
  const double t = f.t_s();
  const long n = f.n_gyro_samples();
  const GyroVec g = sim.Gyro(t);
  EXPECT_EQ(f.AddGyro(t - 0.5, g), GyroSampleStatus::kRejectedOutOfOrder);
  EXPECT_EQ(f.AddGyro(t, g), GyroSampleStatus::kRejectedRepeated);
  EXPECT_EQ(f.AddGyro(kNaN, g), GyroSampleStatus::kRejectedBadTime);
  EXPECT_EQ(f.AddGyro(kInf, g), GyroSampleStatus::kRejectedBadTime);
  EXPECT_EQ(f.AddGyro(t + 0.01, GyroVec::Zero(3)), GyroSampleStatus::kRejectedWrongSize);
  EXPECT_EQ(f.q().coeffs(), q.coeffs());
  EXPECT_EQ(f.P(), p);
  EXPECT_EQ(f.bias_rad_s(), b);
  EXPECT_EQ(f.t_s(), t);
  EXPECT_EQ(f.n_gyro_samples(), n);
  for (auto s : {GyroSampleStatus::kRejectedOutOfOrder, GyroSampleStatus::kRejectedRepeated,
                 GyroSampleStatus::kRejectedWrongSize}) {
    EXPECT_EQ(f.n_gyro_status(s), 1) << GyroSampleStatusName(s);
  }
  EXPECT_EQ(f.n_gyro_status(GyroSampleStatus::kRejectedBadTime), 2);
  EXPECT_EQ(f.AddGyro(t + 0.01, g), GyroSampleStatus::kAccepted);  // and it goes on
}

// One sample tagged a million seconds ahead is refused (the following ones, in order, are taken); a
// real 30 s gap in the gyro stream is taken when the second sample after it confirms it, and the
// attitude then restarts from the next star fix (status failed until then).
TEST(BadInput, TimeJumpsAreConfirmedBeforeTheyAreBelieved) {
  AnalyticFusion sim;
  OnlineFusion f(sim.unit, FuseOptions{});
  RunAnalytic(
      &sim, &f, 60,
      [](long k, double* t, GyroVec*) {
        if (k == 2000) *t += 1e6;
      },
      [](long k, GyroSampleStatus s) {
        EXPECT_EQ(s, k == 2000 ? GyroSampleStatus::kRejectedTimeJump : GyroSampleStatus::kAccepted) << k;
      });
  ExpectWithin3Sigma(f, sim, 60);

  AnalyticFusion gap_sim;
  OnlineFusion g(gap_sim.unit, FuseOptions{});
  RunAnalytic(&gap_sim, &g, 20, NoEdit, AllAccepted);
  // Gyros silent from 20 s to 50 s (no star fixes either): the stream resumes at 50.01 s.
  EXPECT_EQ(g.AddGyro(50.01, gap_sim.Gyro(50.01)), GyroSampleStatus::kRejectedTimeJump);
  EXPECT_EQ(g.AddGyro(50.02, gap_sim.Gyro(50.02)), GyroSampleStatus::kAcceptedAfterGap);
  EXPECT_TRUE(g.restart_pending());
  EXPECT_EQ(g.last_restart(), RestartReason::kGyroGap);
  EXPECT_EQ(g.Status(), FusionStatus::kFailed);
  for (int k = 3; k <= 98; ++k) EXPECT_EQ(g.AddGyro(50 + 0.01 * k, gap_sim.Gyro(50 + 0.01 * k)), GyroSampleStatus::kAccepted);
  Mat3 r;
  const Quat qs = gap_sim.Star(50.98, &r);
  EXPECT_EQ(g.AddAttitude(50.98, qs, r).status, UpdateStatus::kInitialised);
  EXPECT_FALSE(g.restart_pending());
  EXPECT_EQ(g.n_restarts(), 1);
  for (int k = 99; k <= 3000; ++k) {
    const double t = 50 + 0.01 * k;
    g.AddGyro(t, gap_sim.Gyro(t));
    if (k % 100 == 0) {
      const Quat q = gap_sim.Star(t, &r);
      g.AddAttitude(t, q, r);
    }
  }
  ExpectWithin3Sigma(g, gap_sim, 80);
  EXPECT_EQ(g.Status(), FusionStatus::kOk);
}

// The clock goes back 30 s at 40 s (or the last accepted time tag was wrong): the samples are
// refused until policy.resync_after_samples of them have followed one another, then the stream's time
// is taken and the attitude restarts from the next fix. A corrupt first time tag is the same case.
TEST(BadInput, AClockGoneBackIsFollowedAfterARunOfSamples) {
  AnalyticFusion sim;
  OnlineFusion f(sim.unit, FuseOptions{});
  RunAnalytic(&sim, &f, 40, NoEdit, AllAccepted);
  const int n = FusionPolicy{}.resync_after_samples;
  Mat3 r;
  for (int k = 1; k <= 1000; ++k) {
    const double t = 10 + 0.01 * k;  // the true time is 40 s later
    const GyroSampleStatus s = f.AddGyro(t, sim.Gyro(t + 30));
    EXPECT_EQ(s, k < n    ? GyroSampleStatus::kRejectedOutOfOrder
                 : k == n ? GyroSampleStatus::kAcceptedTimeReset
                          : GyroSampleStatus::kAccepted)
        << k;
    if (k == n) {
      EXPECT_TRUE(f.restart_pending());
      EXPECT_EQ(f.last_restart(), RestartReason::kTimeReset);
      EXPECT_EQ(f.Status(), FusionStatus::kFailed);
    }
    if (k % 100 == 0) {
      const Quat q = sim.Star(t + 30, &r);  // the truth of the true time, tagged on the new clock
      EXPECT_EQ(f.AddAttitude(t, q, r).status, k == 100 ? UpdateStatus::kInitialised : UpdateStatus::kAccepted) << k;
    }
  }
  const Vec3 e = RotationVectorFromQuat(sim.Truth(50).conjugate() * f.q());
  for (int a = 0; a < 3; ++a) EXPECT_LT(std::abs(e[a]), 3 * f.attitude_sigma_rad()[a]) << a;

  AnalyticFusion sim2;
  OnlineFusion g(sim2.unit, FuseOptions{});
  EXPECT_EQ(g.AddGyro(1e6, sim2.Gyro(0.01)), GyroSampleStatus::kAccepted);  // nothing to compare it with
  for (int k = 1; k <= n; ++k) {
    EXPECT_EQ(g.AddGyro(0.01 * k, sim2.Gyro(0.01 * k)),
              k < n ? GyroSampleStatus::kRejectedOutOfOrder : GyroSampleStatus::kAcceptedTimeReset);
  }
  EXPECT_EQ(g.AddGyro(0.01 * (n + 1), sim2.Gyro(0.01 * (n + 1))), GyroSampleStatus::kAccepted);
}

// Star fixes: before the filter's time, at the same time as the last, with a NaN, far in the future.
TEST(BadInput, BadMeasurementsAreRefusedWithTheirReason) {
  AnalyticFusion sim;
  OnlineFusion f(sim.unit, FuseOptions{});
  RunAnalytic(&sim, &f, 10, NoEdit, AllAccepted);
  Mat3 r;
  const Quat q = sim.Star(10.0, &r);
  EXPECT_EQ(f.AddAttitude(9.5, q, r).status, UpdateStatus::kRejectedLate);
  EXPECT_EQ(f.AddAttitude(10.0, q, r).status, UpdateStatus::kRejectedRepeated);  // the run's last fix was at 10 s
  Quat q_nan = q;
  q_nan.x() = kNaN;
  EXPECT_EQ(f.AddAttitude(10.0, q_nan, r).status, UpdateStatus::kRejectedBadInput);
  EXPECT_EQ(f.AddAttitude(kNaN, q, r).status, UpdateStatus::kRejectedBadInput);
  EXPECT_EQ(f.AddAttitude(10.0, q, Mat3::Identity() * kInf).status, UpdateStatus::kRejectedBadInput);
  EXPECT_EQ(f.AddAttitude(10.0, q, Mat3::Zero()).status, UpdateStatus::kRejectedBadInput);
  EXPECT_EQ(f.AddAttitude(1e6, q, r).status, UpdateStatus::kRejectedTimeJump);
  EXPECT_EQ(f.n_late(), 1);
  EXPECT_EQ(f.n_repeated_measurements(), 1);
  EXPECT_EQ(f.n_bad_measurements(), 4);
  EXPECT_DOUBLE_EQ(f.t_s(), 10.0);
  // The run goes on to 60 s with its fixes taken.
  for (int k = 1001; k <= 6000; ++k) {
    const double t = 0.01 * k;
    EXPECT_EQ(f.AddGyro(t, sim.Gyro(t)), GyroSampleStatus::kAccepted);
    if (k % 100 == 0) {
      const Quat qs = sim.Star(t, &r);
      EXPECT_TRUE(f.AddAttitude(t, qs, r).accepted) << t;
    }
  }
  ExpectWithin3Sigma(f, sim, 60);
}

// The net under the checks: with the range check opened up, an output of 1e300 deg/h overflows the
// propagation. The filter keeps its last finite state, says failed (a restart pending), and restarts
// from the next star fix.
TEST(BadInput, ANonFiniteStateRestartsFromTheNextFix) {
  AnalyticFusion sim;
  FuseOptions o;
  o.policy.max_gyro_output_dph = std::numeric_limits<double>::max();
  o.fdi = false;  // (the parity monitor would take the overflow for a fault)
  OnlineFusion f(sim.unit, o);
  int failed = 0;
  RunAnalytic(
      &sim, &f, 60,
      [](long k, double*, GyroVec* g) {
        if (k == 3050) g->setConstant(1e300);
      },
      [&](long k, GyroSampleStatus) {
        EXPECT_TRUE(f.q().coeffs().allFinite()) << k;
        EXPECT_TRUE(f.P().allFinite()) << k;
        failed += f.Status() == FusionStatus::kFailed;
      });
  EXPECT_EQ(failed, 51);  // the samples from 30.50 s to 31.00 s, before the fix at 31 s
  EXPECT_EQ(f.n_restarts(), 1);
  EXPECT_EQ(f.last_restart(), RestartReason::kNonFinite);
  ExpectWithin3Sigma(f, sim, 60);
}

// No star fix for five minutes: the gyros carry the attitude, its covariance grows to cover the drift
// (the error stays within 3 sigma), and the first fix after the silence is taken.
TEST(BadInput, StarsSilentForMinutes) {
  AnalyticFusion sim;
  OnlineFusion f(sim.unit, FuseOptions{});
  RunAnalytic(&sim, &f, 60, NoEdit, AllAccepted);
  for (long k = 6001; k <= 36000; ++k) EXPECT_EQ(f.AddGyro(0.01 * k, sim.Gyro(0.01 * k)), GyroSampleStatus::kAccepted);
  const Vec3 err = RotationVectorFromQuat(sim.Truth(360.0).conjugate() * f.q());
  const Vec3 sigma = f.attitude_sigma_rad();
  for (int a = 0; a < 3; ++a) EXPECT_LT(std::abs(err[a]), 3 * sigma[a]) << a;
  EXPECT_EQ(f.Status(), FusionStatus::kOk);
  Mat3 r;
  const Quat q = sim.Star(360.0, &r);
  EXPECT_TRUE(f.AddAttitude(360.0, q, r).accepted);
  ExpectWithin3Sigma(f, sim, 360);
}

// Gyros silent for minutes while the star tracker goes on: the first fix beyond the gap is refused
// (it could be a corrupt time tag), the second restarts the filter, and each later one too (nothing
// carries the attitude between them): a star-only attitude, status degraded.
TEST(BadInput, GyrosSilentForMinutes) {
  AnalyticFusion sim;
  OnlineFusion f(sim.unit, FuseOptions{});
  RunAnalytic(&sim, &f, 30, NoEdit, AllAccepted);
  Mat3 r;
  for (int t = 31; t <= 200; ++t) {
    const Quat q = sim.Star(t, &r);
    const MekfUpdate u = f.AddAttitude(t, q, r);
    if (t <= 40) {
      EXPECT_TRUE(u.accepted) << t;  // within policy.max_gyro_gap_s: propagated with the held rate
      continue;
    }
    EXPECT_EQ(u.status, UpdateStatus::kInitialised) << t;  // more than 10 s after the last gyro sample
    EXPECT_EQ(f.Status(), FusionStatus::kDegraded);
    ExpectWithin3Sigma(f, sim, t, 5);  // each estimate is one fix (5 / 5 / 30 arcsec): 5 sigma over 160
  }
  EXPECT_EQ(f.last_restart(), RestartReason::kGyroGap);
}

// The unit processor: frames of the wrong size or stride are that head's "bad_frame", a wrong number
// of views or a NaN time tag every head's; nothing throws, and a bad gyro sample's status comes back.
TEST(BadInput, UnitProcessorReportsBadFramesAsStatuses) {
  const auto processor = testing::TwoHeadProcessor(DefaultFourFogUnit(), UnitProcessorOptions{});
  UnitProcessor& p = *processor;
  const Image16 small(64, 64, 100);
  FrameReport f;
  ASSERT_NO_THROW(f = p.OnFrames(1.0, {small.view(), ImageView{}}));
  EXPECT_EQ(f.heads[0].status, SolveStatus::kBadFrame);
  EXPECT_STREQ(SolveStatusName(f.heads[0].status), "bad_frame");
  EXPECT_EQ(f.heads[1].status, SolveStatus::kNoFrame);
  EXPECT_EQ(f.status, SolveStatus::kBadFrame);
  const Image16 full(512, 512, 100);
  ImageView short_stride = full.view();
  short_stride.stride = 100;
  ASSERT_NO_THROW(f = p.OnFrames(2.0, {ImageView{}, short_stride}));
  EXPECT_EQ(f.heads[1].status, SolveStatus::kBadFrame);
  ASSERT_NO_THROW(f = p.OnFrames(3.0, {ImageView{}}));
  EXPECT_EQ(f.status, SolveStatus::kBadFrame);
  ASSERT_EQ(f.heads.size(), 2u);
  EXPECT_EQ(f.heads[0].status, SolveStatus::kBadFrame);
  ASSERT_NO_THROW(f = p.OnFrames(kNaN, {full.view(), full.view()}));
  EXPECT_EQ(f.status, SolveStatus::kBadFrame);
  EXPECT_EQ(p.Attitude().frames_refused, 4);
  EXPECT_FALSE(p.Attitude().valid);
  GyroVec g = GyroVec::Zero(4);
  EXPECT_EQ(p.OnGyroSample(0.01, g), GyroSampleStatus::kAccepted);
  EXPECT_EQ(p.OnGyroSample(0.005, g), GyroSampleStatus::kRejectedOutOfOrder);
  g[0] = kNaN;
  EXPECT_EQ(p.OnGyroSample(0.02, g), GyroSampleStatus::kAcceptedPartial);
  EXPECT_EQ(p.Attitude().gyro_samples_refused, 1);
  EXPECT_EQ(p.Attitude().gyro_samples_partial, 1);
}

}  // namespace
}  // namespace ssiu
