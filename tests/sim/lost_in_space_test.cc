// Lost in space among false objects (issue 14): Kelvins-style scenes, and the chance probability's
// calibration on inputs where every solve is false. CI-sized; the 10^4-trial versions are in
// lost_in_space_longtest.cc and their figures in docs/results.md.
#include <algorithm>
#include <cstdio>

#include "lis_campaign.h"

namespace ssiu {
namespace {

using namespace testing;

// 10 x 7.5 deg, 1920 x 1440 px, 20 microradian noise, 0-80 false objects as bright as the stars.
TEST(LostInSpace, KelvinsScenesAmongFalseObjects) {
  const SceneCampaign c = RunKelvinsScenes(60, 1, KelvinsIdentifyOptions());
  int with6 = 0, solved6 = 0;
  for (const auto& [k, v] : c.by_stars)
    if (k >= 6) with6 += v.first, solved6 += v.second;
  std::printf("60 scenes: >= 4 stars %d/%d solved, 3 stars %d/%d, wrong %d\n", c.solved4, c.with4, c.solved3, c.with3,
              c.wrong);
  EXPECT_EQ(c.wrong, 0);
  EXPECT_EQ(solved6, with6) << "every scene with 6 or more stars";
  EXPECT_GE(c.solved4, 0.8 * c.with4);
}

// Uniformly random centroids (8-30): every solve is false. At a threshold of 0.05 the observed rate
// must not exceed it (150 trials: P(Binomial(150, 0.05) > 15) < 0.5%); at 1e-3 at most 2 of 100
// (P(Binomial(100, 1e-3) > 2) = 1.6e-4). The 10^4-trial figures are in docs/results.md.
TEST(LostInSpace, ChanceProbabilityIsCalibratedOnRandomCentroids) {
  IdentifyOptions io;
  io.timeout_ms = 0;
  io.pattern_centroids = 40;
  io.max_false_match_prob = 0.05;
  const Calibration loose = RunRandomCentroids(150, 9000, io, 30);
  std::printf("random centroids at 0.05: %d of %d solved\n", loose.false_solves, loose.trials);
  EXPECT_LE(loose.false_solves, 15);
  io.max_false_match_prob = 1e-3;
  EXPECT_LE(RunRandomCentroids(100, 19000, io, 30).false_solves, 2);
}

// Small random sets (8-12 centroids: few hypotheses, few other centroids as evidence): the false-solve
// rate at every threshold at once, from the best chance probability of each whole search
// (RandomSetsBestChance). Two of the 10^4-trial calibration's random sets (11 and 23 centroids, chance
// 2.6e-5 and 2.7e-5) were solved at the default 1e-4, a hint that small sets are under-counted; 4 x
// 10^5 sets of 8-12 centroids measured 6x below the threshold at 1e-3 and 1e-4 (docs/results.md,
// session 17). Measured here on 3000 sets: 65 below 0.1, 10 below 0.01, 1 below 1e-3; the bounds allow 0.1 and 0.01 of
// them with a binomial margin (P(Binomial(3000, 0.01) > 50) ~ 1e-4), so the test fails if a term of
// the chance probability loses a factor of ~2.5 at 0.01 or ~5 at 0.1.
TEST(LostInSpace, SmallRandomSetsChanceIsConservative) {
  IdentifyOptions io;
  io.timeout_ms = 0;
  io.pattern_centroids = 40;
  const std::vector<double> best = RandomSetsBestChance(3000, 40000000, io, 8, 12);
  const auto below = [&](double a) {
    return static_cast<int>(std::count_if(best.begin(), best.end(), [&](double p) { return p <= a; }));
  };
  std::printf("3000 random sets of 8-12 centroids: best chance <= 0.1: %d, <= 0.01: %d, <= 1e-3: %d\n", below(0.1),
              below(0.01), below(1e-3));
  EXPECT_LE(below(0.1), 300 + 3 * 17);
  EXPECT_LE(below(0.01), 30 + 20);
  EXPECT_LE(below(1e-3), 3 + 6);
}

// The measured bug: a focal length 10 % long with a 12 % tolerance matched 69 deg off at a chance
// probability of 5e-6. Real stars, focal length 5-15 % wrong, tolerance 15 %: no wrong solve, and
// most scenes still solved (with the focal length found).
TEST(LostInSpace, WrongFocalLengthInToleranceModeIsNeverAConfidentWrongMatch) {
  IdentifyOptions io = KelvinsIdentifyOptions();
  io.max_false_match_prob = 1e-3;
  io.max_hypotheses = 20000;  // a deterministic budget (a 15 % search is long)
  const Calibration c = RunWrongFocal(30, 500, 15.0, io);
  std::printf("focal length 5-15 %% wrong, tolerance 15 %%: %d wrong of %d\n", c.false_solves, c.trials);
  EXPECT_EQ(c.false_solves, 0);
  // 18/30 before the chance probability took the factor j (j + 1) for the data-chosen match count
  // (docs/identify.md, step 5); 17/30 after.
  EXPECT_GE(c.solved, 0.55 * c.trials);
}

// Three solves of the 10^4-trial tolerance-mode calibration (docs/results.md) that were right, or
// nearly, but off by 2-116 arcmin in roll at a reported sigma of 21-47 arcsec: one match inconsistent
// with the others (a merged double 49 arcsec from its catalog position at a corner; a false object at a
// corner with the five right stars in a 100-px clump) pulled the refit. At the default threshold each
// must now be right within max(60", 5 sigma) or no_match.
TEST(LostInSpace, ToleranceModeOutlierDoesNotPullTheRefit) {
  IdentifyOptions io = KelvinsIdentifyOptions();
  io.max_hypotheses = 20000;  // a deterministic budget (a 15 % search is long)
  int solved = 0;
  for (uint64_t seed : {209153, 203376, 202541}) {
    const Calibration c = RunWrongFocal(1, seed, 15.0, io);
    EXPECT_EQ(c.false_solves, 0) << "seed " << seed;
    solved += c.solved;
  }
  EXPECT_GE(solved, 1) << "the 10-star scene (seed 209153) is solved without its outlier";
}

// Photometry (docs/identify.md, step 5): two Kelvins scenes (seed 116: 4 stars among 3 false
// objects; 870: 5 stars among 45) that the geometric chance probability alone leaves at no_match at
// 1e-5 (the default before the four-star changes) and that the fluxes' agreement with the catalog
// magnitudes solves, right. Found among the 1000 scenes of LostInSpaceLong.KelvinsScenes1000. (A third,
// seed 152, is solved by geometry alone since the per-side pattern check and the count weights.)
TEST(LostInSpace, PhotometrySolvesFewStarScenesGeometryAloneCannot) {
  IdentifyOptions with = KelvinsIdentifyOptions(), without = KelvinsIdentifyOptions();
  with.max_false_match_prob = without.max_false_match_prob = 1e-5;
  // The sequential factor H = 1 + ln(max_hypotheses) of the search that found these scenes (13.2;
  // the default budget of 12,000 gives 10.4, under which seed 870 passes 1e-5 by geometry alone).
  with.max_hypotheses = without.max_hypotheses = 200000;
  without.use_photometry = false;
  for (uint64_t seed : {116, 870}) {
    const SceneCampaign a = RunKelvinsScenes(1, seed, with), b = RunKelvinsScenes(1, seed, without);
    EXPECT_EQ(a.with4, 1) << "seed " << seed;
    EXPECT_EQ(a.solved4, 1) << "seed " << seed << ": solved with photometry";
    EXPECT_EQ(a.wrong, 0) << "seed " << seed;
    EXPECT_EQ(b.solved4, 0) << "seed " << seed << ": not solved by geometry alone";
  }
}

// Issue 14 acceptance, CI-sized: the first 300 Kelvins-style scenes (seeds 1-300 of
// LostInSpaceLong.KelvinsScenes1000) with the default options (but systematic_px 0 and no deadline).
// Four-star scenes are solved at the default threshold now: the per-side pattern check (fewer chance
// hypotheses before the right one), the weight 3/4 on a single extra match and the steeper photometric
// calibrator (docs/identify.md, steps 2 and 5) with the default 1e-4. Before: 1 of the 22 four-star
// scenes (default 1e-5), 3 at 1e-3.
TEST(LostInSpace, FourStarScenesSolvedAtTheDefault) {
  const SceneCampaign c = RunKelvinsScenes(300, 1, KelvinsIdentifyOptions());
  const auto& four = c.by_stars.at(4);
  std::printf("first 300 Kelvins scenes: >= 4 stars %d/%d, 4 stars %d/%d, wrong %d\n", c.solved4, c.with4, four.second,
              four.first, c.wrong);
  EXPECT_EQ(c.wrong, 0);
  EXPECT_GE(four.second, 5) << "of " << four.first << " four-star scenes";
  EXPECT_GE(c.solved4, 0.93 * c.with4);  // 267/285 (93.7%); these 300 are harder than the 1000's 95.1%
}

}  // namespace
}  // namespace ssiu
