// gtest prints a status by its name (the operator<< beside each status's Name function, found by ADL):
// a failing EXPECT_EQ(result.status, SolveStatus::kSolved) says "no_match", not "4-byte object <01-00 00-00>".
#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include "identify/identify.h"
#include "identify/solve_status.h"
#include "identify/star_catalog.h"

namespace ssiu {
namespace {

TEST(StatusPrintTest, SolveStatusPrintsItsName) {
  EXPECT_EQ(::testing::PrintToString(SolveStatus::kNoMatch), "no_match");
  for (SolveStatus s : {SolveStatus::kSolved, SolveStatus::kNoMatch, SolveStatus::kTooFewStars, SolveStatus::kNoFrame,
                        SolveStatus::kBadFrame})
    EXPECT_EQ(::testing::PrintToString(s), SolveStatusName(s));
}

TEST(StatusPrintTest, SearchStopPrintsItsName) {
  EXPECT_EQ(::testing::PrintToString(SearchStop::kHypothesisBudget), "hypothesis_budget");
  EXPECT_EQ(::testing::PrintToString(SearchStop::kNone), "none");
}

TEST(StatusPrintTest, CatalogDirStatePrintsItsName) {
  EXPECT_EQ(::testing::PrintToString(CatalogDirState::kIncomplete), "incomplete");
  for (CatalogDirState s :
       {CatalogDirState::kAbsent, CatalogDirState::kIncomplete, CatalogDirState::kDamaged, CatalogDirState::kOk})
    EXPECT_EQ(::testing::PrintToString(s), CatalogDirStateName(s));
  EXPECT_NONFATAL_FAILURE(EXPECT_EQ(CatalogDirState::kDamaged, CatalogDirState::kOk), "damaged");
}

TEST(StatusPrintTest, FailureMessageNamesBothStatuses) {
  EXPECT_NONFATAL_FAILURE(EXPECT_EQ(SolveStatus::kNoMatch, SolveStatus::kSolved), "no_match");
  EXPECT_NONFATAL_FAILURE(EXPECT_EQ(SolveStatus::kNoMatch, SolveStatus::kSolved), "solved");
}

}  // namespace
}  // namespace ssiu
