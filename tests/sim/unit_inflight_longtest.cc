// The in-flight calibration's acceptance: 20 simulated slewing missions (seeds 1-20), scale factors and
// misalignments within 3 sigma, attitude error in the 5-minute outage at least 3x smaller, for the batch
// (`fuse --calibrate-unit`) and for the processor's recursive estimator (label `long`).
#include <cstdio>

#include "sim/unit_inflight_mc.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(UnitInflightLong, TwentyMissions) {
  testing::InflightScore s;
  for (uint64_t seed = 1; seed <= 20; ++seed) testing::RunInflightCase(seed, &s);
  std::printf("%s\n", s.Describe().c_str());
  EXPECT_EQ(s.cases, 20);
  EXPECT_GE(s.Fraction(), 0.95);
  // 80 gyros x 3 dof: the mean NEES has a standard deviation of sqrt(6/80) = 0.27.
  EXPECT_GT(s.MeanNees(), 3 - 3 * 0.27);
  EXPECT_LT(s.MeanNees(), 3 + 3 * 0.27);
  EXPECT_GT(std::sqrt(s.nominal2), 3 * std::sqrt(s.calibrated2));
  // The processor's estimator, at the outage's start: estimated and applied in every mission, its
  // estimates within 3 sigma, and the outage error at least 3x smaller than without it.
  EXPECT_EQ(s.online_applied, 20);
  EXPECT_EQ(s.online_parameters, 240);
  EXPECT_GE(s.online_within_3sigma, 0.95 * s.online_parameters);
  EXPECT_GT(s.OnlineMeanNees(), 3 - 3 * 0.27);
  EXPECT_LT(s.OnlineMeanNees(), 3 + 3 * 0.27);
  EXPECT_GT(std::sqrt(s.online_nominal2), 3 * std::sqrt(s.online_calibrated2));
}

}  // namespace
}  // namespace ssiu
