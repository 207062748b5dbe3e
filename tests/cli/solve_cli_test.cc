// `ssiu catalog build`, `ssiu solve` and `ssiu track` end to end on simulated frames: the JSON
// contract, the attitude against the simulator's truth, side outputs, and bad input.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>

#include "core/attitude.h"
#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using Result = testing::SsiuResult;
Result Ssiu(const std::string& args) { return testing::RunSsiu(args); }

Quat QuatOf(const Json& q) { return FromWxyz(q[0], q[1], q[2], q[3]); }

class SolveCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(testing::TempDir("solve_cli"));
    // One catalog for the default 16.6 deg camera, built once through the CLI.
    build_ = new Result(Ssiu("catalog build --fov-deg 16.6 --out " + *dir_ + "/cat"));
  }
  static void TearDownTestSuite() {
    delete dir_;
    delete build_;
  }
  static std::string Path(const std::string& n) { return *dir_ + "/" + n; }
  static std::string* dir_;
  static Result* build_;
};
std::string* SolveCli::dir_ = nullptr;
Result* SolveCli::build_ = nullptr;

TEST_F(SolveCli, CatalogBuildWritesACatalog) {
  ASSERT_EQ(build_->status, 0) << build_->output;
  EXPECT_TRUE(std::filesystem::is_directory(Path("cat")));
  EXPECT_FALSE(std::filesystem::is_empty(Path("cat")));
}

// Photometric evidence (docs/identify.md, step 5) through the CLI: a simulated centroid list whose
// fluxes follow the catalog magnitudes is solved with photometric_factor < 1 (evidence for the match);
// --no-photometry reports 1 and a chance probability larger by the same factor (same hypothesis).
TEST_F(SolveCli, PhotometricFactorAndNoPhotometry) {
  ASSERT_EQ(Ssiu("simulate frame --random --seed 78 --centroids-only --scene-csv --false-objects 5 --out " + Path("p"))
                .status,
            0);
  const std::string base = "solve --centroids " + Path("p/frame_0000_centroids.csv") + " --camera " +
                           Path("p/camera.json") + " --catalog " + Path("cat") + " --timeout-ms 0 --json ";
  ASSERT_EQ(Ssiu(base + Path("with.json")).status, 0);
  ASSERT_EQ(Ssiu(base + Path("without.json") + " --no-photometry").status, 0);
  const Json a = ReadJsonFile(Path("with.json")), b = ReadJsonFile(Path("without.json"));
  ASSERT_EQ(a["status"], "solved") << a["message"];
  ASSERT_EQ(b["status"], "solved") << b["message"];
  const double fa = a["photometric_factor"].get<double>();
  std::printf("photometric_factor %g; chance %g with, %g without; hypotheses %d, %d\n", fa,
              a["false_match_probability"].get<double>(), b["false_match_probability"].get<double>(),
              a["hypotheses"].get<int>(), b["hypotheses"].get<int>());
  EXPECT_GT(fa, 0.0);
  EXPECT_LT(fa, 1.0);
  EXPECT_EQ(b["photometric_factor"].get<double>(), 1.0);
  if (a["hypotheses"] == b["hypotheses"] && a["matches"].size() == b["matches"].size()) {
    EXPECT_NEAR(a["false_match_probability"].get<double>() / b["false_match_probability"].get<double>(), fa, 1e-6 * fa);
  }
}

TEST_F(SolveCli, SolveFrameMatchesTruthAndWritesOverlayAndWcs) {
  ASSERT_EQ(Ssiu("simulate frame --random --seed 77 --out " + Path("f")).status, 0);
  const Result r =
      Ssiu("solve " + Path("f/frame_0000.png") + " --camera " + Path("f/camera.json") + " --catalog " + Path("cat") +
           " --json " + Path("s.json") + " --overlay " + Path("o.png") + " --wcs " + Path("s.wcs"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Json s = ReadJsonFile(Path("s.json"));
  for (const char* k : {"status", "q", "ra_deg", "dec_deg", "roll_deg", "sigma_cross_arcsec", "sigma_roll_arcsec",
                        "focal_length_px", "false_match_probability", "matches", "timing_ms"}) {
    EXPECT_TRUE(s.contains(k)) << k;
  }
  ASSERT_EQ(s["status"], "solved");
  const Json truth = ReadJsonFile(Path("f/frame_0000.json"));
  const AttitudeErrorSplit e = SplitAttitudeError(QuatOf(s["q"]), QuatOf(truth["q"]));
  EXPECT_LT(e.cross_rad * kRadToArcsec, 5.0);
  EXPECT_LT(std::abs(e.roll_rad) * kRadToArcsec, 60.0);
  EXPECT_GE(s["q"][0].get<double>(), 0.0);  // w >= 0
  ASSERT_GT(s["matches"].size(), 10u);
  for (const char* k : {"x_px", "y_px", "star_id", "mag", "residual_arcsec"})
    EXPECT_TRUE(s["matches"][0].contains(k)) << k;
  // Every matched id is a star the simulator drew.
  std::set<int> drawn;
  for (const auto& t : truth["stars"]) drawn.insert(t["star_id"].get<int>());
  int known = 0;
  for (const auto& m : s["matches"]) known += drawn.count(m["star_id"].get<int>()) > 0;
  EXPECT_GE(known, static_cast<int>(s["matches"].size()) - 1);
  EXPECT_GT(std::filesystem::file_size(Path("o.png")), 1000u);
  std::ifstream wcs(Path("s.wcs"));
  const std::string header((std::istreambuf_iterator<char>(wcs)), std::istreambuf_iterator<char>());
  EXPECT_NE(header.find("CTYPE1"), std::string::npos);
  EXPECT_NE(header.find("RA---TAN"), std::string::npos);
  // A WCS file that cannot be written is an error naming it (was exit 0 with no file).
  const Result w = Ssiu("solve " + Path("f/frame_0000.png") + " --camera " + Path("f/camera.json") + " --catalog " +
                        Path("cat") + " --json " + Path("s2.json") + " --wcs /nonexistent_dir/s.wcs");
  EXPECT_EQ(w.status, 1) << w.output;
  EXPECT_THAT(w.output, ::testing::HasSubstr("/nonexistent_dir/s.wcs: cannot write file"));
  // ... and the only line: the summary is printed after every output (it used to come first).
  EXPECT_EQ(std::count(w.output.begin(), w.output.end(), '\n'), 1) << w.output;
  const Result o = Ssiu("solve " + Path("f/frame_0000.png") + " --camera " + Path("f/camera.json") + " --catalog " +
                        Path("cat") + " --json " + Path("s3.json") + " --overlay /nonexistent_dir/o.png");
  EXPECT_EQ(o.status, 1) << o.output;
  EXPECT_THAT(o.output, ::testing::HasSubstr("/nonexistent_dir/o.png"));
  EXPECT_EQ(std::count(o.output.begin(), o.output.end(), '\n'), 1) << o.output;
}

TEST_F(SolveCli, SolveFromCentroidsCsvAndNoiseGivesNoSolution) {
  ASSERT_EQ(Ssiu("simulate frame --random --seed 78 --out " + Path("g")).status, 0);
  const Json truth = ReadJsonFile(Path("g/frame_0000.json"));
  {
    std::ofstream csv(Path("c.csv"));
    csv << "x_px,y_px,flux\n";
    for (const auto& t : truth["stars"]) {
      if (t["mag"].get<double>() < 6.5)
        csv << t["x_px"].get<double>() << "," << t["y_px"].get<double>() << "," << t["flux_adu"].get<double>() << "\n";
    }
  }
  Result r = Ssiu("solve --centroids " + Path("c.csv") + " --camera " + Path("g/camera.json") + " --catalog " +
                  Path("cat") + " --json " + Path("c.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Json s = ReadJsonFile(Path("c.json"));
  ASSERT_EQ(s["status"], "solved");
  EXPECT_LT(AttitudeErrorRad(QuatOf(s["q"]), QuatOf(truth["q"])) * kRadToArcsec, 60.0);

  // Pure noise (no stars, no artefacts): never solved.
  ASSERT_EQ(
      Ssiu("simulate frame --random --seed 79 --mag-max -5 --hot-pixels 0 --cosmic-rays 0 --out " + Path("n")).status,
      0);
  r = Ssiu("solve " + Path("n/frame_0000.png") + " --camera " + Path("n/camera.json") + " --catalog " + Path("cat") +
           " --json " + Path("n.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(ReadJsonFile(Path("n.json"))["status"], "solved");

  // Bad centroid files: exit 1 with one line naming the file.
  std::ofstream(Path("bad.csv")) << "x_px,y_px\n1,2\n3,nan\n";
  r = Ssiu("solve --centroids " + Path("bad.csv") + " --camera " + Path("g/camera.json") + " --catalog " + Path("cat"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, ::testing::HasSubstr("bad.csv"));
  std::ofstream(Path("noy.csv")) << "x_px,flux\n1,2\n";
  r = Ssiu("solve --centroids " + Path("noy.csv") + " --camera " + Path("g/camera.json") + " --catalog " + Path("cat"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, ::testing::HasSubstr("y_px"));
}

TEST_F(SolveCli, TrackFollowsASlewAfterALostInSpaceStart) {
  // Three frames 0.2 deg apart along RA: lost in space first, then tracking.
  for (int k = 0; k < 3; ++k) {
    const std::string out = Path("t" + std::to_string(k));
    ASSERT_EQ(Ssiu("simulate frame --ra-deg " + std::to_string(150.0 + 0.2 * k) +
                   " --dec-deg 20 --roll-deg 30 --seed " + std::to_string(90 + k) + " --out " + out)
                  .status,
              0);
  }
  const Result r =
      Ssiu("track " + Path("t0/frame_0000.png") + " " + Path("t1/frame_0000.png") + " " + Path("t2/frame_0000.png") +
           " --camera " + Path("t0/camera.json") + " --catalog " + Path("cat") + " --json " + Path("t.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Json t = ReadJsonFile(Path("t.json"));
  const Json frames = t.is_array() ? t : t["frames"];
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0]["mode"], "lost_in_space");
  EXPECT_EQ(frames[2]["mode"], "tracking");
  for (int k = 0; k < 3; ++k) {
    ASSERT_EQ(frames[k]["status"], "solved") << k;
    const Json truth = ReadJsonFile(Path("t" + std::to_string(k) + "/frame_0000.json"));
    EXPECT_LT(SplitAttitudeError(QuatOf(frames[k]["q"]), QuatOf(truth["q"])).cross_rad * kRadToArcsec, 5.0) << k;
  }
}

// camera.json's vignetting and hot_pixels (a fitted camera of `discover frames`) are used by `ssiu solve`
// and `ssiu track` (the vignetting out of the fluxes: stronger photometric evidence) and carried by
// `ssiu calibrate` into the camera it writes.
TEST_F(SolveCli, CameraVignettingAndHotPixelsUsedBySolveKeptByCalibrate) {
  ASSERT_EQ(Ssiu("simulate frame --random --seed 91 --count 3 --vignetting 0.6 --out " + Path("v")).status, 0);
  Json cam = ReadJsonFile(Path("v/camera.json"));
  const Json truth = ReadJsonFile(Path("v/frame_0000.json"));
  cam["vignetting"] = 0.6;
  cam["hot_pixels"] = Json::array();
  for (const auto& a : truth["artefacts"])
    if (a["type"] == "hot_pixel")
      cam["hot_pixels"].push_back({std::lround(a["x_px"].get<double>()), std::lround(a["y_px"].get<double>())});
  std::ofstream(Path("v/cam_model.json")) << cam.dump();
  double ln_factor[2] = {0, 0}, first_factor[2] = {0, 0};
  int k = 0;
  for (const char* c : {"v/camera.json", "v/cam_model.json"}) {
    for (int i = 0; i < 3; ++i) {
      const std::string f = Path("v/frame_000" + std::to_string(i));
      ASSERT_EQ(
          Ssiu("solve " + f + ".png --camera " + Path(c) + " --catalog " + Path("cat") + " --json " + f + ".out.json")
              .status,
          0);
      const Json r = ReadJsonFile(f + ".out.json");
      ASSERT_EQ(r["status"], "solved") << c << " " << i << ": " << r["message"];
      EXPECT_LT(AttitudeErrorRad(QuatOf(r["q"]), QuatOf(ReadJsonFile(f + ".json")["q"])) * kRadToArcsec, 30.0);
      ln_factor[k] += std::log(r["photometric_factor"].get<double>());
      if (i == 0) first_factor[k] = r["photometric_factor"].get<double>();
    }
    ++k;
  }
  std::printf("ln photometric factor over 3 frames: vignetting left in %.1f, taken out %.1f\n", ln_factor[0],
              ln_factor[1]);
  EXPECT_LT(ln_factor[1], ln_factor[0] - 10);
  // `ssiu track` as well: its first frame (lost in space) is `ssiu solve`'s with the same camera.
  ASSERT_EQ(Ssiu("track " + Path("v/frame_0000.png") + " --camera " + Path("v/cam_model.json") + " --catalog " +
                 Path("cat") + " --json " + Path("v/track.json"))
                .status,
            0);
  const Json tr = ReadJsonFile(Path("v/track.json"));
  ASSERT_EQ(tr[0]["status"], "solved");
  EXPECT_NEAR(tr[0]["photometric_factor"].get<double>(), first_factor[1], 1e-9 * first_factor[1]);
  EXPECT_LT(first_factor[1], first_factor[0]);
  const Result cal =
      Ssiu("calibrate " + Path("v/frame_0000.png") + " " + Path("v/frame_0001.png") + " " + Path("v/frame_0002.png") +
           " --camera " + Path("v/cam_model.json") + " --out " + Path("v/cal.json"));
  ASSERT_EQ(cal.status, 0) << cal.output;
  const Json out = ReadJsonFile(Path("v/cal.json"));
  EXPECT_EQ(out["vignetting"], cam["vignetting"]);
  EXPECT_EQ(out["hot_pixels"], cam["hot_pixels"]);
}

}  // namespace
}  // namespace ssiu
