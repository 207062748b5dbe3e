// Acceptance of `ssiu discover frames` (issue 7): 35 simulated frame sets of 4 frames, each with one
// hidden camera effect (distortion, focal length, principal point, vignetting, persistent hot
// pixels, PSF width) or none; the right cause in >= 90 %, `none` never confused with the transient
// hot pixels and cosmic rays, the fitted camera reduces residuals, held-out gain of the others > 1.
#include <algorithm>
#include <cstdio>
#include <map>

#include "core/astrometry.h"

#include "discover_frames_mc.h"
#include "discover_frames_oov.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(DiscoverFramesLong, ThirtyFiveFrameSetsAcceptance) {
  const auto s = testing::RunFrameMonteCarlo(35, 4, 31337, true);
  std::cout << "right cause " << s.right << "/" << s.sets << ", geometric fits reducing residuals "
            << s.geometric_reduced << "/" << s.geometric_named << ", parameters within 3 sigma " << s.params_3sigma
            << "/" << s.params << ", none " << s.none_right << "/" << s.none_sets << ", hot_pixels/psf_shape gain > 1 "
            << s.other_gain << "/" << s.other_named << ", persistent pixels found " << s.hot_found << "/"
            << s.hot_detectable << " (> 1000 ADU), false " << s.hot_false << "\n";
  EXPECT_GE(s.right, 0.9 * s.sets);
  EXPECT_EQ(s.geometric_reduced, s.geometric_named);
  EXPECT_GE(s.none_right, 0.9 * s.none_sets);
  EXPECT_EQ(s.other_gain, s.other_named);
  EXPECT_GE(s.hot_found, 0.8 * s.hot_detectable);
}

// False alarms: 20 more sets with nothing hidden (transient hot pixels and cosmic rays only).
TEST(DiscoverFramesLong, TwentyCleanSetsStayNone) {
  const auto s = testing::RunFrameMonteCarlo(20, 4, 4242, true, {"none"});
  std::cout << "clean sets named none: " << s.none_right << "/" << s.none_sets << "\n";
  EXPECT_GE(s.none_right, 19);
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

// Issue 18: `unexplained` for frames. Synthetic frame sets (discover_frames_oov.h), 8 per effect:
// the vocabulary's causes named right, clean sets `none`, effects outside the vocabulary
// `unexplained` >= 90 % with a wrongly named cause <= 5 %.
TEST(DiscoverFramesLong, OutOfVocabularyIsUnexplained) {
  std::vector<std::string> effects = testing::SyntheticFrameCauses();
  for (const auto& e : testing::OutOfVocabularyFrameEffects()) effects.push_back(e);
  const auto r = testing::RunSyntheticFrames(effects, 8, 9100, true);
  int in_sets = 0, in_right = 0, out_sets = 0, out_unexplained = 0, out_wrong = 0;
  for (const auto& [effect, s] : r) {
    std::printf("%-16s right %d/%d, unexplained %d, none %d, wrong cause %d\n", effect.c_str(), s.right, s.sets,
                s.unexplained, s.none, s.wrong);
    const bool inside = std::find(testing::SyntheticFrameCauses().begin(), testing::SyntheticFrameCauses().end(),
                                  effect) != testing::SyntheticFrameCauses().end();
    (inside ? in_sets : out_sets) += s.sets;
    (inside ? in_right : out_unexplained) += s.right;
    if (!inside) out_wrong += s.wrong;
  }
  std::printf("inside the vocabulary (and none): right %d/%d; outside: unexplained %d/%d, wrong cause %d/%d\n",
              in_right, in_sets, out_unexplained, out_sets, out_wrong, out_sets);
  EXPECT_GE(in_right, 0.9 * in_sets);
  EXPECT_GE(out_unexplained, 0.9 * out_sets);
  EXPECT_LE(out_wrong, 0.05 * out_sets);
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

// Issue 31: two and three effects together (28 combinations, 3 sets each, 12 frames of ~50 stars):
// every injected cause named >= 90 %, a cause not injected in <= 5 % of the sets, the injected
// parameters within 3 sigma, the final held-out residual at the noise level.
TEST(DiscoverFramesLong, SeveralEffectsTogether) {
  const auto combos = testing::MultiEffectCombinations();
  const auto s = testing::RunMultiEffectFrames(combos, 3, 31000, true);
  std::printf(
      "%zu combinations, %d sets: all injected named %d, injected causes named %d/%d, a cause not injected %d, "
      "unexplained %d, parameters within 3 sigma %d/%d, final residual at the noise level %d\n",
      combos.size(), s.sets, s.all_named, s.injected_named, s.injected, s.wrong, s.unexplained, s.params_3sigma,
      s.params, s.at_noise);
  EXPECT_GE(s.all_named, 0.9 * s.sets);
  EXPECT_LE(s.wrong, 0.05 * s.sets);
  EXPECT_GE(s.params_3sigma, 0.95 * s.params);
  EXPECT_GE(s.at_noise, 0.9 * s.sets);
}

// False alarms of the stepwise search on clean sets of the same size (12 frames): none >= 95 %.
TEST(DiscoverFramesLong, CleanTwelveFrameSetsStayNone) {
  const auto s = testing::RunMultiEffectFrames({"none"}, 60, 52000, false);
  std::printf("clean 12-frame sets: none %d/%d, a cause named %d, unexplained %d\n", s.sets - s.wrong - s.unexplained,
              s.sets, s.wrong, s.unexplained);
  EXPECT_GE(s.sets - s.wrong - s.unexplained, 0.95 * s.sets);
}

}  // namespace
}  // namespace ssiu


namespace ssiu {
namespace {

// Power of the residual test (issue 31): a position effect outside the vocabulary (bump, twist,
// stitch, cti), alone or beside a focal-length error, scaled to 0.1-3 times the RMS centroid noise;
// 10 sets each of 4 frames x 45 stars and of 12 frames x 50 stars. Printed as a table
// (docs/discrepancy.md); a leftover of 1x the noise and more is found in every set.
TEST(DiscoverFramesLong, ResidualTestPower) {
  const double ratios[] = {0.1, 0.2, 0.3, 0.5, 1, 3};
  for (const auto& size : {std::pair<int, int>{4, 45}, std::pair<int, int>{12, 50}}) {
    std::printf("%d frames x %d stars: unexplained of 10 at leftover / noise", size.first, size.second);
    for (double r : ratios) std::printf(" %5.1f", r);
    std::printf("\n");
    for (const char* e : {"bump", "twist", "stitch", "cti", "focal_length+twist", "lens_distortion+bump"}) {
      std::printf("  %-22s", e);
      for (double r : ratios) {
        const int found = testing::LeftoverDetected(e, r, 10, 8800, size.first, size.second);
        std::printf(" %5d", found);
        if (r >= 1) {
          EXPECT_EQ(found, 10) << e << " at " << r << "x noise";
        }
      }
      std::printf("\n");
    }
  }
}

}  // namespace
}  // namespace ssiu

namespace ssiu {
namespace {

// Issue 31 on simulated images: the 28 combinations of discover_frames_oov.h (k2 0.5-1.5 beside k1 in the
// lens_distortion_k2 ones; aberration: frames drawn at a time with the Earth's velocity, ~30 km/s, and
// solved without it), one set each of 12 frames (16.6 deg, noise, cosmic rays, transient hot pixels).
TEST(DiscoverFramesLong, SeveralEffectsOnSimulatedImages) {
  int sets = 0, all_named = 0, wrong = 0, params = 0, within = 0;
  const auto combos = testing::MultiEffectCombinations();
  for (size_t i = 0; i < combos.size(); ++i) {
    const testing::SyntheticFrameSet draw = testing::MakeSyntheticFrameSet(combos[i], 41000 + i, 1, 1);
    const Camera nominal = MakeCamera(1024, 1024, 16.6);
    Camera truth = nominal;
    std::map<std::string, double> want = draw.truth;
    if (want.count("focal_length_px")) truth.focal_length_px = want["focal_length_px"];
    if (want.count("cx_px")) truth.cx_px = want["cx_px"], truth.cy_px = want["cy_px"];
    if (want.count("k1")) truth.distortion.k1 = want["k1"];
    if (want.count("k2")) truth.distortion.k2 = want["k2"];
    if (want.count("pixel_aspect")) truth.focal_length_y_px = truth.focal_length_px * want["pixel_aspect"];
    FrameSimOptions so;
    so.vignetting = want.count("vignetting") ? want["vignetting"] : 0.0;
    const bool aberration = want.count("velocity_x_kms") > 0;
    if (aberration) {
      so.time_utc = "2026-03-20T12:00:00Z";  // the Earth's velocity then: the truth
      so.proper_motion = false;
      const Vec3 v = EarthBarycentricVelocityMS(ParseUtcIso8601(so.time_utc, "test")) / 1e3;
      for (int a = 0; a < 3; ++a) want["velocity_" + std::string(1, "xyz"[a]) + "_kms"] = v[a];
    }
    const SolvedFrameSet set = testing::SimulateAndSolve(truth, nominal, so, 52000 + 100 * i, 12);
    const FrameDiscovery d = DiscoverFrames(set, nominal, testing::McDiscoverOptions());
    const std::vector<std::string> inj = testing::InjectedCauses(combos[i]);
    std::string chain, ps;
    int named = 0, bad = 0;
    for (const auto& c : d.causes) {
      chain += (chain.empty() ? "" : "+") + c.cause;
      bad += std::find(inj.begin(), inj.end(), c.cause) == inj.end();
    }
    for (const auto& c : inj) {
      named += std::any_of(d.causes.begin(), d.causes.end(), [&](const FrameCauseStep& s) { return s.cause == c; });
    }
    for (const auto& [k, v] : want) {
      if (!d.parameters.count(k)) continue;
      const double dev = (d.parameters.at(k) - v) / d.sigmas.at(k);
      ++params, within += std::abs(dev) <= 3;
      char b[64];
      std::snprintf(b, sizeof b, " %s %+.1fsig", k.c_str(), dev);
      ps += b;
    }
    ++sets, all_named += named == static_cast<int>(inj.size()), wrong += bad > 0;
    std::printf("%-46s -> %-46s %s %d/12 solved, %d stars, rms %.2f -> %.2f arcsec%s\n", combos[i].c_str(),
                chain.c_str(), d.cause == "unexplained" ? "unexplained" : "", d.frames_solved, d.stars,
                d.residual_rms_before_arcsec, d.residual_rms_after_arcsec, ps.c_str());
  }
  std::printf("simulated images, %d sets: all injected named %d, a cause not injected %d, parameters within 3 sigma %d/%d\n",
              sets, all_named, wrong, within, params);
  EXPECT_GE(all_named, 0.9 * sets);
  EXPECT_LE(wrong, 0.05 * sets + 0.5);
  EXPECT_GE(within, 0.9 * params);
}

}  // namespace
}  // namespace ssiu
