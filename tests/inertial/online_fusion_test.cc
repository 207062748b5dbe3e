// The estimator core (inertial/online_fusion.h) and the unit processor (inertial/unit_processor.h) on
// hand-made inputs: the policies of FuseOptions::policy, a late measurement, missing and wrong frames.
// Their runs on simulated missions and gyro logs are in tests/sim/ (mission_test.cc: they need the
// simulator, a stage above this one).
#include "inertial/online_fusion.h"

#include <cmath>
#include <functional>
#include <limits>
#include <memory>

#include "core/attitude.h"
#include "core/camera.h"
#include "core/error.h"
#include "inertial/propagate.h"
#include "inertial/unit_processor.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

// A measurement older than the filter's time is refused, not applied at the wrong time.
TEST(OnlineFusion, RefusesALateMeasurement) {
  const GyroUnit unit = DefaultFourFogUnit();
  OnlineFusion f(unit, FuseOptions{});
  const Mat3 r = Mat3::Identity() * 1e-10;
  EXPECT_TRUE(f.AddAttitude(0.0, Quat::Identity(), r).accepted);
  for (int k = 1; k <= 10; ++k) f.AddGyro(k * 0.01, GyroVec::Zero(4));
  EXPECT_FALSE(f.AddAttitude(0.05, Quat::Identity(), r).accepted);
  EXPECT_EQ(f.n_late(), 1);
  EXPECT_TRUE(f.AddAttitude(0.1, Quat::Identity(), r).accepted);
}

// A filter started at the identity with a 5 arcsec fix sees fixes 0.01 rad (2,063 arcsec) away: NIS
// about 8e4, far over the gate. They are refused policy.accept_after_rejections times in a row, then
// the next one is taken ungated, whatever the run length is set to.
TEST(OnlineFusion, TakesTheFixAfterTheConfiguredRunOfRejections) {
  const double s = 5 * kArcsecToRad;
  const Mat3 r = Mat3::Identity() * (s * s);
  const Quat off = QuatFromRotationVector(Vec3(0.01, 0, 0));
  for (int run : {FusionPolicy{}.accept_after_rejections, 2}) {
    FuseOptions o;
    o.policy.accept_after_rejections = run;
    o.fdi = false;
    OnlineFusion f(DefaultFourFogUnit(), o);
    ASSERT_TRUE(f.AddAttitude(0.0, Quat::Identity(), r).accepted);
    for (int k = 1; k <= run + 1; ++k) {
      f.AddGyro(k * 0.01, GyroVec::Zero(4));
      const MekfUpdate u = f.AddAttitude(k * 0.01, off, r);
      EXPECT_GT(u.nis, 1e4) << run << " " << k;
      EXPECT_EQ(u.accepted, k == run + 1) << run << " " << k;
    }
    EXPECT_EQ(f.n_rejected(), run);
    EXPECT_LT(AttitudeErrorRad(f.q(), off), 0.5 * 0.01);  // the accepted fix moved the estimate
  }
  EXPECT_EQ(FusionPolicy{}.accept_after_rejections, 5);  // the default docs/inertial.md states
}

std::string PolicyError(const std::function<void(FusionPolicy*)>& set) {
  FuseOptions o;
  set(&o.policy);
  try {
    OnlineFusion f(DefaultFourFogUnit(), o);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(OnlineFusion, BadPolicyIsAnInputErrorNamingTheField) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(PolicyError([](FusionPolicy*) {}), "(no error)");
  EXPECT_EQ(PolicyError([](FusionPolicy* p) { p->settle_after_isolation_s = 0; }), "(no error)");
  EXPECT_THAT(PolicyError([](FusionPolicy* p) { p->accept_after_rejections = 0; }),
              HasSubstr("fuse options: policy.accept_after_rejections must be >= 1"));
  EXPECT_THAT(PolicyError([](FusionPolicy* p) { p->isolation_chain_gap_s = 0; }),
              HasSubstr("policy.isolation_chain_gap_s"));
  EXPECT_THAT(PolicyError([&](FusionPolicy* p) { p->failed_after_s = nan; }), HasSubstr("policy.failed_after_s"));
  EXPECT_THAT(PolicyError([](FusionPolicy* p) { p->settle_after_isolation_s = -1; }),
              HasSubstr("policy.settle_after_isolation_s"));
  EXPECT_THAT(PolicyError([&](FusionPolicy* p) { p->bias_history_s = inf; }), HasSubstr("policy.bias_history_s"));
}

// The on-board API directly: no frame from any head is a result, not an error; before the first
// solved frame there is no attitude; a frame of the wrong size is refused ("bad_frame", no exception:
// tests/inertial/bad_input_test.cc has the other bad inputs). (Two 512x512
// heads of 16.6 deg 90 deg apart, as the default mission's.)
TEST(UnitProcessor, ReportsMissingFramesAndRefusesAWrongSize) {
  OpticalHead h1;
  h1.camera = MakeCamera(512, 512, 16.6);
  OpticalHead h2 = h1;
  h2.q_body_from_sensor = Quat(Eigen::AngleAxisd(90 * kDegToRad, Vec3::UnitX()));
  const std::vector<OpticalHead> heads = {h1, h2};
  const GyroUnit unit = DefaultFourFogUnit();
  const UnitProcessorOptions options;
  const auto id = std::make_shared<const StarIdentifier>(MakeIdentifierForCamera("", h1.camera, 0.0));
  UnitProcessor p(heads, {id, id}, unit, options);
  EXPECT_FALSE(p.Attitude().valid);
  const FrameReport none = p.OnFrames(0.0, {ImageView{}, ImageView{}});
  EXPECT_EQ(none.status, SolveStatus::kNoFrame);
  EXPECT_EQ(none.heads_solved, 0);
  EXPECT_FALSE(p.Attitude().valid);
  const Image16 small(64, 64, 100);
  EXPECT_EQ(p.OnFrames(1.0, {small.view(), ImageView{}}).heads[0].status, SolveStatus::kBadFrame);
  EXPECT_EQ(p.OnFrames(1.0, {ImageView{}}).status, SolveStatus::kBadFrame);
  EXPECT_THROW(UnitProcessor(std::vector<OpticalHead>(4, h1), {id, id, id, id}, unit, options), InputError);
}

}  // namespace
}  // namespace ssiu
