// The deterministic work budget of lost in space (docs/identify.md, "Work budget"): the search is
// bounded by counts (max_hypotheses, max_patterns), a search stopped by one reports how far it got,
// and the answer does not depend on time unless the optional timeout_ms is what stopped it.
#include <cmath>
#include <memory>

#include "core/attitude.h"
#include "core/catalog.h"
#include "core/error.h"
#include "core/rng.h"
#include "identify/identify.h"
#include "identify/synthetic.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using testing::Bsc166;
using testing::MakeSyntheticFrame;
using testing::SyntheticOptions;

const Camera& Cam() {
  static const Camera cam = MakeCamera(1024, 1024, 16.6);
  return cam;
}

// `n` centroids at random positions with random fluxes: no star pattern, never a solution.
std::vector<Centroid> RandomCentroids(int n, uint64_t seed) {
  Rng rng(seed);
  std::vector<Centroid> c(n);
  for (auto& x : c) {
    x.x_px = rng.Uniform(0, Cam().width - 1);
    x.y_px = rng.Uniform(0, Cam().height - 1);
    x.flux = rng.Uniform(1, 100);
  }
  return c;
}

// A frame at a known attitude with bright false stars that enter the first patterns, so the right
// triangle comes after some chance hypotheses.
struct Scene {
  testing::SyntheticFrame frame;
  Quat q;
};
Scene HardScene(uint64_t seed) {
  Rng rng(seed);
  SyntheticOptions so;
  so.false_stars = 25;
  so.mag_max = 6.0;
  const Quat q = QuatFromUniform(rng.Uniform(), rng.Uniform(), rng.Uniform());
  return {MakeSyntheticFrame(Bsc166().catalog(), Cam(), q, so, &rng), q};
}

IdentifyOptions Options() {
  IdentifyOptions io;
  io.systematic_px = 0.0;
  return io;
}

// Everything a caller sees of the answer, compared bit for bit.
void ExpectSameAnswer(const Identification& a, const Identification& b) {
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.stop, b.stop);
  EXPECT_EQ(a.hypotheses, b.hypotheses);
  EXPECT_EQ(a.patterns, b.patterns);
  EXPECT_EQ(a.false_match_probability, b.false_match_probability);
  EXPECT_EQ(a.q_inertial_from_sensor.coeffs(), b.q_inertial_from_sensor.coeffs());
  ASSERT_EQ(a.matches.size(), b.matches.size());
  for (size_t i = 0; i < a.matches.size(); ++i) {
    EXPECT_EQ(a.matches[i].centroid, b.matches[i].centroid);
    EXPECT_EQ(a.matches[i].star_id, b.matches[i].star_id);
  }
}

// Random centroids cannot be solved; a hypothesis budget smaller than the full search stops it with
// exactly that many hypotheses, whatever the clock.
TEST(WorkBudget, HypothesisBudgetStopsTheSearchAtTheCount) {
  const std::vector<Centroid> c = RandomCentroids(60, 11);
  IdentifyOptions io = Options();
  const Identification full = Bsc166().Identify(c, Cam(), io);
  ASSERT_EQ(full.status, SolveStatus::kNoMatch);
  ASSERT_EQ(full.stop, SearchStop::kExhausted);  // C(60, 3) triangles, far below max_patterns
  EXPECT_GT(full.patterns, 0);
  EXPECT_LE(full.patterns, 60 * 59 * 58 / 6);  // the triangles that fit the catalog's field
  ASSERT_GT(full.hypotheses, 20) << "a budget test needs a search with hypotheses";
  for (int budget : {1, 7, full.hypotheses / 2, full.hypotheses - 1}) {
    io.max_hypotheses = budget;
    const Identification r = Bsc166().Identify(c, Cam(), io);
    EXPECT_EQ(r.status, SolveStatus::kNoMatch);
    EXPECT_EQ(r.stop, SearchStop::kHypothesisBudget) << budget;
    EXPECT_EQ(r.hypotheses, budget);
    EXPECT_LE(r.patterns, full.patterns);
  }
  io.max_hypotheses = full.hypotheses;  // just enough: the whole search
  const Identification r = Bsc166().Identify(c, Cam(), io);
  EXPECT_EQ(r.stop, SearchStop::kExhausted);
  EXPECT_EQ(r.hypotheses, full.hypotheses);
  EXPECT_EQ(r.patterns, full.patterns);
}

TEST(WorkBudget, PatternBudgetStopsTheSearchAtTheCount) {
  const std::vector<Centroid> c = RandomCentroids(60, 12);
  IdentifyOptions io = Options();
  for (int budget : {1, 100, 5000}) {
    io.max_patterns = budget;
    const Identification r = Bsc166().Identify(c, Cam(), io);
    EXPECT_EQ(r.status, SolveStatus::kNoMatch);
    EXPECT_EQ(r.stop, SearchStop::kPatternBudget) << budget;
    EXPECT_EQ(r.patterns, budget);
  }
  io.max_patterns = 0;
  EXPECT_THROW(io.Check(), InputError);
}

// A solvable frame: the right attitude (against the synthetic truth) at hypothesis h; a budget of
// h - 1 stops before it (no_match, h - 1 counted), a budget of h finds the same solution.
TEST(WorkBudget, SolutionNeedsItsHypothesisCount) {
  const Scene s = HardScene(5);
  const IdentifyOptions io = Options();
  const Identification r = Bsc166().Identify(s.frame.centroids, Cam(), io);
  ASSERT_EQ(r.status, SolveStatus::kSolved) << r.message;
  EXPECT_EQ(r.stop, SearchStop::kAccepted);
  EXPECT_LT(AttitudeErrorRad(r.q_inertial_from_sensor, s.q) * kRadToArcsec, 60.0);
  for (const auto& m : r.matches) EXPECT_EQ(m.star_id, s.frame.truth_id[m.centroid]);
  ASSERT_GT(r.hypotheses, 1) << "the scene should need chance hypotheses first";
  IdentifyOptions less = io;
  less.max_hypotheses = r.hypotheses - 1;
  const Identification stopped = Bsc166().Identify(s.frame.centroids, Cam(), less);
  EXPECT_EQ(stopped.status, SolveStatus::kNoMatch);
  EXPECT_EQ(stopped.stop, SearchStop::kHypothesisBudget);
  EXPECT_EQ(stopped.hypotheses, r.hypotheses - 1);
  IdentifyOptions just = io;
  just.max_hypotheses = r.hypotheses;  // a smaller sequential factor: the same hypothesis passes
  const Identification again = Bsc166().Identify(s.frame.centroids, Cam(), just);
  ASSERT_EQ(again.status, SolveStatus::kSolved);
  EXPECT_EQ(again.hypotheses, r.hypotheses);
  EXPECT_EQ(again.q_inertial_from_sensor.coeffs(), r.q_inertial_from_sensor.coeffs());
  EXPECT_LE(again.false_match_probability, r.false_match_probability);
}

// The same frames solve bit-identically with no clock (timeout_ms 0, the default), with a safety
// limit far above the work (1 hour), and twice in a row: the answer depends on the counts only.
TEST(WorkBudget, AnswerDoesNotDependOnTheClock) {
  EXPECT_EQ(IdentifyOptions{}.timeout_ms, 0.0);
  for (uint64_t seed : {5, 6, 7}) {
    const Scene s = HardScene(seed);
    IdentifyOptions io = Options();
    const Identification a = Bsc166().Identify(s.frame.centroids, Cam(), io);
    const Identification b = Bsc166().Identify(s.frame.centroids, Cam(), io);
    io.timeout_ms = 3.6e6;
    const Identification c = Bsc166().Identify(s.frame.centroids, Cam(), io);
    ASSERT_EQ(a.status, SolveStatus::kSolved) << seed << ": " << a.message;
    EXPECT_LT(AttitudeErrorRad(a.q_inertial_from_sensor, s.q) * kRadToArcsec, 60.0);
    ExpectSameAnswer(a, b);
    ExpectSameAnswer(a, c);
  }
  // And an unsolvable frame stopped by the budget reports the same count either way.
  const std::vector<Centroid> c = RandomCentroids(60, 13);
  IdentifyOptions io = Options();
  io.max_hypotheses = 10;
  const Identification a = Bsc166().Identify(c, Cam(), io);
  io.timeout_ms = 3.6e6;
  ExpectSameAnswer(a, Bsc166().Identify(c, Cam(), io));
  EXPECT_EQ(a.stop, SearchStop::kHypothesisBudget);
}

// The outer safety limit still works, and says that it (not a count) ended the search.
TEST(WorkBudget, TimeoutIsReportedAsSuch) {
  const std::vector<Centroid> c = RandomCentroids(100, 14);  // ~160,000 triangles: milliseconds of work
  IdentifyOptions io = Options();
  io.timeout_ms = 1e-3;
  const Identification r = Bsc166().Identify(c, Cam(), io);
  EXPECT_EQ(r.status, SolveStatus::kNoMatch);
  EXPECT_EQ(r.stop, SearchStop::kTimeout);
  EXPECT_LT(r.hypotheses, io.max_hypotheses);
}

}  // namespace
}  // namespace ssiu
