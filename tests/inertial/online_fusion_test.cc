// The estimator core (inertial/online_fusion.h) on hand-made inputs: the policies of FuseOptions::policy.
#include <cmath>
#include <functional>
#include <limits>

#include "core/attitude.h"
#include "core/error.h"
#include "inertial/online_fusion.h"
#include "inertial/propagate.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

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

}  // namespace
}  // namespace ssiu
