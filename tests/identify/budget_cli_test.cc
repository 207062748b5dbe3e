// `ssiu solve --max-hypotheses N` is the lost-in-space work budget (docs/identify.md, "Work budget"):
// a simulated centroid list whose right triangle is the h-th hypothesis is solved (at the
// simulator's attitude) with N = h and not with N = h - 1, which reports exactly h - 1 hypotheses.
#include "core/attitude.h"
#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(WorkBudgetCli, SolveHonoursMaxHypotheses) {
  const std::string dir = testing::TempDir("budget_cli");
  auto ssiu = [](const std::string& args) {
    const testing::SsiuResult r = testing::RunSsiu(args);
    EXPECT_EQ(r.status, 0) << args << "\n" << r.output;
  };
  ssiu("catalog build --fov-deg 16.6 --out " + dir + "/cat");
  // Seed 5 with 30 false objects needs ~100 hypotheses (measured; asserted below to be > 1).
  ssiu("simulate frame --random --seed 5 --centroids-only --false-objects 30 --out " + dir + "/s");
  const std::string base = "solve --centroids " + dir + "/s/frame_0000_centroids.csv --camera " + dir +
                           "/s/camera.json --catalog " + dir + "/cat --json ";
  ssiu(base + dir + "/default.json");
  const Json truth = ReadJsonFile(dir + "/s/frame_0000.json");
  const Json d = ReadJsonFile(dir + "/default.json");
  ASSERT_EQ(d["status"], "solved") << d["message"];
  auto quat = [](const Json& q) { return FromWxyz(q[0], q[1], q[2], q[3]); };
  EXPECT_LT(AttitudeErrorRad(quat(d["q"]), quat(truth["q"])) * kRadToArcsec, 60.0);
  const int h = d["hypotheses"];
  ASSERT_GT(h, 1);
  ssiu(base + dir + "/less.json --max-hypotheses " + std::to_string(h - 1));
  const Json less = ReadJsonFile(dir + "/less.json");
  EXPECT_EQ(less["status"], "no_match");
  EXPECT_EQ(less["hypotheses"], h - 1);
  EXPECT_EQ(less["search_stop"], "hypothesis_budget");
  EXPECT_EQ(d["search_stop"], "accepted");
  EXPECT_GE(d["patterns"].get<int>(), 1);
  EXPECT_LE(less["patterns"].get<int>(), d["patterns"].get<int>());
  ssiu(base + dir + "/just.json --max-hypotheses " + std::to_string(h) + " --timeout-ms 0");
  const Json just = ReadJsonFile(dir + "/just.json");
  ASSERT_EQ(just["status"], "solved") << just["message"];
  EXPECT_EQ(just["hypotheses"], h);
  EXPECT_EQ(just["q"], d["q"]);
  EXPECT_EQ(just["matches"].size(), d["matches"].size());
  // A budget below 1 is a usage error naming the field.
  const testing::SsiuResult bad = testing::RunSsiu(base + dir + "/bad.json --max-hypotheses 0");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.output.find("max_hypotheses"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace ssiu
