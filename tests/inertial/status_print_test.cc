// gtest prints the inertial stage's statuses by name (the operator<< beside each Name function).
#include <gtest/gtest.h>

#include "inertial/fdi.h"
#include "inertial/fuse.h"
#include "inertial/mekf.h"
#include "inertial/online_fusion.h"

namespace ssiu {
namespace {

TEST(InertialStatusPrintTest, StatusesPrintTheirNames) {
  EXPECT_EQ(::testing::PrintToString(GyroSampleStatus::kRejectedTimeJump), "rejected_time_jump");
  EXPECT_EQ(::testing::PrintToString(UpdateStatus::kRejectedGate), "rejected_nis");
  EXPECT_EQ(::testing::PrintToString(RestartReason::kGyroGap), "gyro_gap");
  EXPECT_EQ(::testing::PrintToString(FaultStatus::kIsolated), "isolated");
  EXPECT_EQ(::testing::PrintToString(FusionStatus::kDegraded), "degraded");
  EXPECT_EQ(::testing::PrintToString(FuseStatus::kNoStarData), FuseStatusName(FuseStatus::kNoStarData));
}

}  // namespace
}  // namespace ssiu
