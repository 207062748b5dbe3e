// Several camera effects at once (issue 31), CI size: the stepwise extension of `ssiu discover frames`
// on synthetic frame sets (discover_frames_oov.h, no images) of 12 frames and about 600 stars with two
// or three effects hidden together. The acceptance over every combination is in
// discover_frames_longtest.cc. Also issue 31's examples on simulated images.
#include <algorithm>
#include <cstdio>

#include "discover_frames_oov.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(DiscoverFramesMulti, TwoAndThreeEffectsAllNamedWithUnbiasedParameters) {
  const std::vector<std::string> combos = {"focal_length+lens_distortion", "lens_distortion+principal_point+vignetting",
                                           "focal_length+principal_point+vignetting", "pixel_aspect+aberration"};
  const auto s = testing::RunMultiEffectFrames(combos, 1, 3100, true);
  EXPECT_EQ(s.all_named, s.sets);
  EXPECT_EQ(s.wrong, 0);
  EXPECT_EQ(s.params_3sigma, s.params);
  EXPECT_EQ(s.at_noise, s.sets);
}

// Issue 31's examples on simulated images (16.6 deg, 12 frames, noise, cosmic rays, transient hot
// pixels): a focal length 0.4 % long with k1 = -0.08; k1 = -0.08 with the principal point 25 px off and
// vignetting 0.3; focal length 0.4 %, principal point and vignetting. Every effect named, the parameters
// within 3 sigma of the truth, nothing left `unexplained`.
TEST(DiscoverFramesMulti, IssueExamplesOnSimulatedImages) {
  struct Example {
    double focal_ppm, k1, dcx_px, dcy_px, vignetting;
    std::vector<std::string> causes;
  };
  const std::vector<Example> examples = {
      {4000, -0.08, 0, 0, 0, {"focal_length", "lens_distortion"}},
      {0, -0.08, 25, -18, 0.3, {"lens_distortion", "principal_point", "vignetting"}},
      {4000, 0, -20, 15, 0.3, {"focal_length", "principal_point", "vignetting"}}};
  for (size_t e = 0; e < examples.size(); ++e) {
    const Example& x = examples[e];
    const Camera nominal = MakeCamera(1024, 1024, 16.6);
    Camera truth = nominal;
    truth.focal_length_px *= 1 + x.focal_ppm * 1e-6;
    truth.distortion.k1 = x.k1;
    truth.cx_px += x.dcx_px, truth.cy_px += x.dcy_px;
    FrameSimOptions so;
    so.vignetting = x.vignetting;
    const SolvedFrameSet set = testing::SimulateAndSolve(truth, nominal, so, 7100 + 100 * e, 12);
    const FrameDiscovery d = DiscoverFrames(set, nominal, testing::McDiscoverOptions());
    std::string chain;
    for (const auto& c : d.causes) chain += " " + c.cause;
    std::printf("example %zu: %d/%d solved, %d stars, cause %s, chain%s, rms %.2f -> %.2f arcsec\n", e,
                d.frames_solved, d.frames, d.stars, d.cause.c_str(), chain.c_str(), d.residual_rms_before_arcsec,
                d.residual_rms_after_arcsec);
    EXPECT_NE(d.cause, "unexplained");
    ASSERT_EQ(d.causes.size(), x.causes.size()) << chain;
    for (const auto& c : x.causes) {
      EXPECT_TRUE(std::any_of(d.causes.begin(), d.causes.end(), [&](const FrameCauseStep& s) { return s.cause == c; }))
          << c;
    }
    const std::map<std::string, double> want = {{"focal_length_px", truth.focal_length_px},
                                                {"k1", truth.distortion.k1},
                                                {"cx_px", truth.cx_px},
                                                {"cy_px", truth.cy_px},
                                                {"vignetting", x.vignetting}};
    for (const auto& [k, v] : want) {
      if (!d.parameters.count(k)) continue;
      std::printf("  %s %.6g +- %.3g (true %.6g)\n", k.c_str(), d.parameters.at(k), d.sigmas.at(k), v);
      EXPECT_LE(std::abs(d.parameters.at(k) - v), 3 * d.sigmas.at(k)) << k;
    }
  }
}

// The fitted camera is the final joint model: every named camera parameter in it (k2 too), the
// aberration's velocity not (it is not a camera property).
TEST(DiscoverFramesMulti, FittedCameraCarriesEveryNamedParameter) {
  const auto c = testing::MakeSyntheticFrameSet("lens_distortion_k2+principal_point+aberration", 3300, 12, 50);
  const FrameDiscovery d = DiscoverFrames(c.set, c.nominal, {});
  ASSERT_EQ(d.causes.size(), 3u);
  ASSERT_EQ(d.causes[0].cause == "lens_distortion" ? d.causes[0].terms.size() : 1u, 1u);
  EXPECT_DOUBLE_EQ(d.fitted_camera.distortion.k1, d.parameters.at("k1"));
  EXPECT_DOUBLE_EQ(d.fitted_camera.distortion.k2, d.parameters.at("k2"));
  EXPECT_DOUBLE_EQ(d.fitted_camera.cx_px, d.parameters.at("cx_px"));
  EXPECT_DOUBLE_EQ(d.fitted_camera.cy_px, d.parameters.at("cy_px"));
  EXPECT_DOUBLE_EQ(d.fitted_camera.focal_length_px, c.nominal.focal_length_px);
  EXPECT_NEAR(d.parameters.at("k2"), c.truth.at("k2"), 3 * d.sigmas.at("k2"));
  EXPECT_NEAR(d.parameters.at("velocity_x_kms"), c.truth.at("velocity_x_kms"), 3 * d.sigmas.at("velocity_x_kms"));
  // Correlations of the named camera parameters: k1 and k2 are nearly collinear over a 16.6 deg field.
  bool k1k2 = false;
  for (const auto& r : d.correlations) {
    EXPECT_LE(std::abs(r.r), 1.0);
    if (r.a == "k1" && r.b == "k2") {
      k1k2 = true;
      EXPECT_LT(r.r, -0.8);
    }
  }
  EXPECT_TRUE(k1k2);
}

// A model that carries vignetting (camera.json "vignetting", as fitted_camera writes it): the cause tests
// only what is left beyond it. Fed its own fitted law back, vignetting is not named again; with half the
// true law in the model, the rest is named and the whole law (the parameter) lands on the truth.
TEST(DiscoverFramesMulti, VignettingOfTheModelIsTakenOut) {
  const auto c = testing::MakeSyntheticFrameSet("vignetting", 3500, 12, 50);
  const double v_true = c.truth.at("vignetting");
  auto named = [](const FrameDiscovery& d) {
    return std::any_of(d.causes.begin(), d.causes.end(),
                       [](const FrameCauseStep& e) { return e.cause == "vignetting"; });
  };
  const FrameDiscovery d1 = DiscoverFrames(c.set, c.nominal, {});
  ASSERT_TRUE(named(d1));
  const double v1 = d1.parameters.at("vignetting");
  EXPECT_NEAR(v1, v_true, 3 * d1.sigmas.at("vignetting"));
  EXPECT_EQ(d1.fitted_camera_extras.vignetting, v1);
  FrameDiscoverOptions o;
  o.vignetting = v1;
  const FrameDiscovery d2 = DiscoverFrames(c.set, c.nominal, o);
  EXPECT_FALSE(named(d2));
  EXPECT_EQ(d2.cause, "none");
  EXPECT_EQ(d2.fitted_camera_extras.vignetting, v1);  // the model's, kept
  o.vignetting = 0.5 * v_true;
  const FrameDiscovery d3 = DiscoverFrames(c.set, c.nominal, o);
  ASSERT_TRUE(named(d3));
  EXPECT_NEAR(d3.parameters.at("vignetting"), v_true, 3 * d3.sigmas.at("vignetting"));
  EXPECT_NEAR(d3.parameters.at("vignetting"), v1, 0.1 * d1.sigmas.at("vignetting"));
}

// The residual test sees what no named cause explains: a twist, a local bump, a stitched sensor or a
// magnitude-dependent shift of 3 times the centroid noise (RMS), alone or beside a focal-length error,
// is `unexplained`, with the vocabulary's cause kept as partial_cause. The power at smaller sizes is
// in discover_frames_longtest.cc.
TEST(DiscoverFramesMulti, ThreeTimesNoiseLeftoverIsUnexplained) {
  if (testing::kUnderSanitizer)
    GTEST_SKIP() << "its frame-set discoveries (too long for the sanitizer run's share of CI time); the residual test "
                    "runs there in "
                    "every frames discovery (DiscoverFramesMulti.IssueExamplesOnSimulatedImages, "
                    "DiscoverFramesMulti.TwoAndThreeEffectsAllNamedWithUnbiasedParameters)";
  for (const char* e : {"twist", "bump", "stitch", "cti", "focal_length+twist"}) {
    EXPECT_EQ(testing::LeftoverDetected(e, 3.0, 2, 6100, 12, 50), 2) << e;
  }
  const auto c = testing::MakeSyntheticFrameSet("focal_length+twist", 6100, 12, 50, 2.0);
  const FrameDiscovery d = DiscoverFrames(c.set, c.nominal, {});
  EXPECT_EQ(d.cause, "unexplained");
  EXPECT_EQ(d.partial_cause, "focal_length");
  ASSERT_FALSE(d.causes.empty());
  EXPECT_EQ(d.causes.front().cause, "focal_length");
}

}  // namespace
}  // namespace ssiu
