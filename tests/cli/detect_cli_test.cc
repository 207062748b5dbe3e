// `ssiu simulate frame` and `ssiu detect` end to end: the JSON contract, exit status, and a one-line
// error naming the file for every kind of bad input.
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <vector>

#include "core/image.h"
#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

using Result = testing::SsiuResult;
Result Ssiu(const std::string& args) { return testing::RunSsiu(args); }

int Lines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

class CliTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::TempDir("cli"); }
  std::string Path(const std::string& name) const { return dir_ + "/" + name; }
  void Write(const std::string& name, const std::string& bytes) const {
    std::ofstream(Path(name), std::ios::binary) << bytes;
  }
  // Exit 1, exactly one line, naming `needle` (the file) and mentioning `what`.
  void ExpectBadInput(const std::string& args, const std::string& needle, const std::string& what) const {
    const Result r = Ssiu(args);
    EXPECT_EQ(r.status, 1) << args << "\n" << r.output;
    EXPECT_EQ(Lines(r.output), 1) << r.output;
    EXPECT_THAT(r.output, HasSubstr(needle));
    EXPECT_THAT(r.output, HasSubstr(what));
  }
  std::string dir_;
};

TEST_F(CliTest, SimulateThenDetectFollowsTheJsonContract) {
  const Result sim = Ssiu("simulate frame --ra-deg 83.8 --dec-deg -5.4 --roll-deg 10 --seed 4 --out " + Path("sim"));
  ASSERT_EQ(sim.status, 0) << sim.output;
  const Json truth = ReadJsonFile(Path("sim/frame_0000.json"));
  for (const char* k : {"q", "ra_deg", "dec_deg", "roll_deg", "stars", "artefacts", "camera", "options"}) {
    EXPECT_TRUE(truth.contains(k)) << k;
  }
  EXPECT_NEAR(truth["ra_deg"].get<double>(), 83.8, 1e-9);
  EXPECT_NEAR(truth["roll_deg"].get<double>(), 10.0, 1e-9);
  ASSERT_GT(truth["stars"].size(), 20u);
  for (const char* k : {"star_id", "mag", "x_px", "y_px", "flux_e", "snr", "saturated"}) {
    EXPECT_TRUE(truth["stars"][0].contains(k)) << k;
  }
  int hot = 0;
  for (const auto& a : truth["artefacts"]) hot += a["type"] == "hot_pixel";
  EXPECT_EQ(hot, 40);

  const Result det = Ssiu("detect " + Path("sim/frame_0000.png") + " --camera " + Path("sim/camera.json") + " --json " +
                          Path("det.json"));
  ASSERT_EQ(det.status, 0) << det.output;
  const Json d = ReadJsonFile(Path("det.json"));
  for (const char* k : {"file", "width", "height", "background_adu", "noise_adu", "stars", "rejected", "timing_ms"}) {
    EXPECT_TRUE(d.contains(k)) << k;
  }
  ASSERT_GT(d["stars"].size(), 20u);
  for (const char* k : {"x_px", "y_px", "flux_adu", "peak_adu", "snr", "npix", "saturated"}) {
    EXPECT_TRUE(d["stars"][0].contains(k)) << k;
  }
  for (size_t i = 1; i < d["stars"].size(); ++i) {
    EXPECT_GE(d["stars"][i - 1]["flux_adu"].get<double>(), d["stars"][i]["flux_adu"].get<double>());
  }
  const std::set<std::string> reasons = {"hot_pixel", "dead_pixel", "defect_map", "cosmic_ray", "streak", "extended"};
  for (const auto& r : d["rejected"]) EXPECT_TRUE(reasons.count(r["reason"].get<std::string>())) << r.dump();
  // The brightest detection is on a drawn star.
  double best = 1e9;
  for (const auto& s : truth["stars"]) {
    best = std::min(best, std::hypot(s["x_px"].get<double>() - d["stars"][0]["x_px"].get<double>(),
                                     s["y_px"].get<double>() - d["stars"][0]["y_px"].get<double>()));
  }
  EXPECT_LT(best, 0.5);
}

TEST_F(CliTest, FitsAndEightBitInputGiveTheSameStars) {
  ASSERT_EQ(Ssiu("simulate frame --random --seed 9 --out " + Path("sim")).status, 0);
  const Frame fr = ReadFrame(Path("sim/frame_0000.png"));
  WriteFits16(Path("f.fits"), fr.image);
  ASSERT_EQ(Ssiu("detect " + Path("sim/frame_0000.png") + " --json " + Path("a.json")).status, 0);
  ASSERT_EQ(Ssiu("detect " + Path("f.fits") + " --json " + Path("b.json")).status, 0);
  const Json a = ReadJsonFile(Path("a.json")), b = ReadJsonFile(Path("b.json"));
  ASSERT_EQ(a["stars"].size(), b["stars"].size());
  EXPECT_DOUBLE_EQ(a["stars"][0]["x_px"].get<double>(), b["stars"][0]["x_px"].get<double>());
}

// --max-stars keeps the brightest N of the default list; 0 lifts the cap (a deep search).
TEST_F(CliTest, MaxStarsKeepsTheBrightestOrLiftsTheCap) {
  ASSERT_EQ(Ssiu("simulate frame --random --seed 9 --out " + Path("sim")).status, 0);
  const std::string frame = Path("sim/frame_0000.png");
  ASSERT_EQ(Ssiu("detect " + frame + " --json " + Path("all.json")).status, 0);
  ASSERT_EQ(Ssiu("detect " + frame + " --max-stars 5 --json " + Path("five.json")).status, 0);
  ASSERT_EQ(Ssiu("detect " + frame + " --threshold-sigma 3 --max-stars 20 --json " + Path("t3cap.json")).status, 0);
  ASSERT_EQ(Ssiu("detect " + frame + " --threshold-sigma 3 --max-stars 0 --json " + Path("t3deep.json")).status, 0);
  const Json all = ReadJsonFile(Path("all.json")), five = ReadJsonFile(Path("five.json"));
  ASSERT_GT(all["stars"].size(), 5u);
  ASSERT_EQ(five["stars"].size(), 5u);
  for (size_t i = 0; i < 5; ++i) {
    EXPECT_NEAR(five["stars"][i]["x_px"].get<double>(), all["stars"][i]["x_px"].get<double>(), 1e-9);
    EXPECT_NEAR(five["stars"][i]["flux_adu"].get<double>(), all["stars"][i]["flux_adu"].get<double>(), 1e-9);
  }
  EXPECT_EQ(ReadJsonFile(Path("t3cap.json"))["stars"].size(), 20u);
  EXPECT_GT(ReadJsonFile(Path("t3deep.json"))["stars"].size(), all["stars"].size());
  ExpectBadInput("detect " + frame + " --max-stars -1 --json -", "--max-stars", "must be >= 0");
}

TEST_F(CliTest, BadImagesExitOneWithOneLineNamingTheFile) {
  ExpectBadInput("detect " + Path("missing.png") + " --json -", "missing.png", "no such file");
  Write("empty.png", "");
  ExpectBadInput("detect " + Path("empty.png") + " --json -", "empty.png", "empty");
  Write("corrupt.png", std::string("\x89PNG\r\n\x1a\n", 8) + "garbage that is not a png stream");
  ExpectBadInput("detect " + Path("corrupt.png") + " --json -", "corrupt.png", "cannot decode");
  Write("text.tiff", "plain text, wrong type");
  ExpectBadInput("detect " + Path("text.tiff") + " --json -", "text.tiff", "cannot decode");
  // Truncated: half of a valid PNG.
  WritePng16(Path("full.png"), Image16(300, 300, 500));
  {
    Image16 im(300, 300, 500);
    im.at(10, 10) = 900;
    WritePng16(Path("full.png"), im);
  }
  std::ifstream in(Path("full.png"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  Write("trunc.png", bytes.substr(0, bytes.size() / 2));
  ExpectBadInput("detect " + Path("trunc.png") + " --json -", "trunc.png", "");
  Write("zero.fits", std::string("SIMPLE  =                    T") + std::string(2849, ' '));
  ExpectBadInput("detect " + Path("zero.fits") + " --json -", "zero.fits", "");
  WritePng16(Path("allzero.png"), Image16(64, 64, 0));
  ExpectBadInput("detect " + Path("allzero.png") + " --json -", "allzero.png", "constant");
  WritePng16(Path("allsat.png"), Image16(64, 64, 65535));
  ExpectBadInput("detect " + Path("allsat.png") + " --json -", "allsat.png", "constant");
  // Smaller than Detect()'s 16x16 minimum: a bad-input error, not an internal one (exit 2).
  Image16 tiny(8, 500, 100);
  tiny.at(3, 3) = 900;
  WritePng16(Path("tiny.png"), tiny);
  ExpectBadInput("detect " + Path("tiny.png") + " --json -", "tiny.png", "too small");
  Image16 mostly(64, 64, 65535);
  for (int x = 0; x < 64; ++x) mostly.at(x, 0) = 100;
  WritePng16(Path("mostlysat.png"), mostly);
  ExpectBadInput("detect " + Path("mostlysat.png") + " --json -", "mostlysat.png", "saturated");
}

TEST_F(CliTest, BadCameraFilesExitOneNamingTheField) {
  ASSERT_EQ(Ssiu("simulate frame --random --seed 2 --out " + Path("sim")).status, 0);
  const std::string frame = Path("sim/frame_0000.png");
  Write("nowidth.json", R"({"height": 1024, "focal_length_px": 3000})");
  ExpectBadInput("detect " + frame + " --camera " + Path("nowidth.json"), "nowidth.json", "width");
  Write("absurd.json", R"({"width": 1024, "height": 1024, "focal_length_px": -5})");
  ExpectBadInput("detect " + frame + " --camera " + Path("absurd.json"), "absurd.json", "focal_length_px");
  Write("nan.json", R"({"width": 1024, "height": 1024, "focal_length_px": "fast"})");
  ExpectBadInput("detect " + frame + " --camera " + Path("nan.json"), "nan.json", "focal_length_px");
  Write("size.json", R"({"width": 640, "height": 480, "focal_length_px": 3000})");
  ExpectBadInput("detect " + frame + " --camera " + Path("size.json"), "frame_0000.png", "640x480");
  Write("broken.json", R"({"width": 1024, )");
  ExpectBadInput("detect " + frame + " --camera " + Path("broken.json"), "broken.json", "JSON");
  ExpectBadInput("simulate frame --camera " + Path("absurd.json") + " --random --out " + Path("o"), "absurd.json",
                 "focal_length_px");
  ExpectBadInput("simulate frame --random --psf-sigma-px -1 --out " + Path("o"), "psf_sigma_px", "");
  ExpectBadInput("simulate frame --random --hot-pixels 1e8 --out " + Path("o"), "hot_pixels", "at most 1e6");
  ExpectBadInput("simulate frame --random --streaks 1e7 --out " + Path("o"), "cosmic_rays", "streaks 1e4");
  // A directory given as camera.json; a NaN or negative gain is refused, not silently ignored.
  ExpectBadInput("detect " + frame + " --camera " + dir_, dir_, "is a directory");
  ExpectBadInput("detect " + frame + " --gain-e-per-adu nan --json -", "--gain-e-per-adu", "finite");
  ExpectBadInput("detect " + frame + " --gain-e-per-adu -2 --json -", "--gain-e-per-adu", ">= 0");
}

TEST_F(CliTest, DemoSolvesItsFrameAgainstTheTruth) {
  // The README's main job: simulate, detect, solve lost-in-space, compare with the truth.
  const Result r = Ssiu("demo --seed 5 --json " + Path("demo.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Json j = ReadJsonFile(Path("demo.json"));
  EXPECT_EQ(j["status"], "solved");
  EXPECT_LT(j["error_cross_arcsec"].get<double>(), 5.0);
  EXPECT_LT(std::abs(j["error_roll_arcsec"].get<double>()), 60.0);
  EXPECT_GE(j["recall_snr10"].get<double>(), 0.95);
}

TEST_F(CliTest, UsageErrorsExitOne) {
  EXPECT_EQ(Ssiu("detect").status, 1);
  EXPECT_EQ(Ssiu("no-such-command").status, 1);
  EXPECT_EQ(Ssiu("simulate frame --out " + Path("o")).status, 1);  // no attitude
  EXPECT_EQ(Ssiu("detect --help").status, 0);
  // An infinite frame interval used to be accepted (times of inf in the output).
  const Result r = Ssiu("track x.png --camera x.json --dt-s inf");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, HasSubstr("--dt-s: must be a finite number > 0"));
}

TEST_F(CliTest, DefectMapFromTheRealMedianFrame) {
  SSIU_REQUIRE_SHARED(median, "openstartracker/median_image.png");
  const Result r = Ssiu("defects build " + median + " --out " + Path("map.png"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Frame map = ReadFrame(Path("map.png"));
  size_t hot = 0;
  for (uint16_t v : map.image.pixels) hot += v == 255;
  // The median of ten frames keeps the sensor's fixed hot pixels and loses the stars.
  EXPECT_GT(hot, 10u);
  EXPECT_LT(hot, map.image.pixels.size() / 100);
  SSIU_REQUIRE_SHARED(img, "openstartracker/img0.png");
  const Result d = Ssiu("detect " + img + " --defects " + Path("map.png") + " --json " + Path("d.json"));
  ASSERT_EQ(d.status, 0) << d.output;
  int defect_rejections = 0;
  const Json dj = ReadJsonFile(Path("d.json"));
  for (const auto& rj : dj["rejected"]) defect_rejections += rj["reason"] == "defect_map";
  EXPECT_GT(defect_rejections, 0);
}

// camera.json's `hot_pixels` (as `discover frames` writes them in its fitted camera) are repaired before
// detection: the simulator's hot pixels, listed, are rejected as the defect map's and none is a star.
TEST_F(CliTest, CameraHotPixelsAreRepairedBeforeDetection) {
  ASSERT_EQ(Ssiu("simulate frame --ra-deg 83.8 --dec-deg -5.4 --roll-deg 10 --seed 4 --out " + Path("sim")).status, 0);
  const Json truth = ReadJsonFile(Path("sim/frame_0000.json"));
  Json cam = ReadJsonFile(Path("sim/camera.json"));
  cam["hot_pixels"] = Json::array();
  std::vector<std::array<double, 2>> hot;
  for (const auto& a : truth["artefacts"]) {
    if (a["type"] != "hot_pixel") continue;
    hot.push_back({a["x_px"].get<double>(), a["y_px"].get<double>()});
    cam["hot_pixels"].push_back({std::lround(hot.back()[0]), std::lround(hot.back()[1])});
  }
  ASSERT_EQ(hot.size(), 40u);
  Write("cam_hot.json", cam.dump());
  // Per run: detections and rejections of each reason on a listed hot pixel.
  auto on_hot = [&](const std::string& camera, const std::string& out) {
    const Result r =
        Ssiu("detect " + Path("sim/frame_0000.png") + " --camera " + Path(camera) + " --json " + Path(out));
    EXPECT_EQ(r.status, 0) << r.output;
    const Json d = ReadJsonFile(Path(out));
    auto near = [&](const Json& s) {
      for (const auto& h : hot)
        if (std::hypot(s["x_px"].get<double>() - h[0], s["y_px"].get<double>() - h[1]) < 0.5) return true;
      return false;
    };
    std::map<std::string, int> n;
    for (const auto& s : d["stars"]) n["star"] += near(s);
    for (const auto& s : d["rejected"]) n[s["reason"].get<std::string>()] += near(s);
    n["all_stars"] = static_cast<int>(d["stars"].size());
    return n;
  };
  std::map<std::string, int> plain = on_hot("sim/camera.json", "plain.json"),
                             listed = on_hot("cam_hot.json", "hot.json");
  std::printf("hot pixels: plain hot_pixel %d defect_map %d star %d; listed hot_pixel %d defect_map %d star %d\n",
              plain["hot_pixel"], plain["defect_map"], plain["star"], listed["hot_pixel"], listed["defect_map"],
              listed["star"]);
  EXPECT_GT(plain["hot_pixel"], 10);  // found on the fly without the list
  EXPECT_EQ(plain["defect_map"], 0);
  EXPECT_EQ(listed["hot_pixel"], 0);  // with it, each is the map's
  // Without the list, one 3 px from a star is taken into its blob; with it, it is the map's.
  EXPECT_GE(listed["defect_map"], plain["hot_pixel"]);
  EXPECT_EQ(listed["star"], 0);
  EXPECT_EQ(listed["all_stars"], plain["all_stars"] - plain["star"]);
}

// camera.json's `psf_sigma_px` is the PSF the detector expects: on defocused optics (sigma 2.4 px) with
// few bright stars the frame's own estimate falls back to 1.2 px or comes out high, and the matched filter
// made for the wrong PSF misses faint stars; with the camera's PSF more of the simulator's stars are found
// and matched, with no more false detections. --psf-sigma-px still overrides it.
TEST_F(CliTest, CameraPsfSigmaIsTheDetectorsExpectedPsf) {
  Write("cam.json", R"({"width": 512, "height": 512, "focal_length_px": 1754.8162132636639})");
  ASSERT_EQ(Ssiu("simulate frame --camera " + Path("cam.json") +
                 " --random --seed 5 --count 6 --psf-sigma-px 2.4 --exposure-s 0.03 --out " + Path("f"))
                .status,
            0);
  Json cam = ReadJsonFile(Path("cam.json"));
  cam["psf_sigma_px"] = 2.4;
  Write("cam_psf.json", cam.dump());
  int found[2] = {0, 0}, spurious[2] = {0, 0}, matched[2] = {0, 0}, assumed = 0;
  for (int i = 0; i < 6; ++i) {
    const std::string f = Path("f/frame_000" + std::to_string(i));
    const Json truth = ReadJsonFile(f + ".json");
    for (int k = 0; k < 2; ++k) {
      const std::string c = Path(k == 0 ? "cam.json" : "cam_psf.json");
      ASSERT_EQ(Ssiu("detect " + f + ".png --camera " + c + " --json " + f + ".det.json").status, 0);
      const Json d = ReadJsonFile(f + ".det.json");
      if (k == 1) {
        EXPECT_EQ(d["psf_sigma_px"], 2.4);
        EXPECT_EQ(d["psf_source"], "given");
      } else if (d["psf_source"] == "assumed") {  // too few bright isolated stars to measure it: says so
        ++assumed;
        EXPECT_EQ(d["psf_sigma_px"], 1.2);
      } else {
        EXPECT_EQ(d["psf_source"], "measured");
        EXPECT_GT(d["psf_sigma_px"].get<double>(), 2.0);
      }
      for (const auto& s : d["stars"]) {
        bool star = false;
        for (const auto& t : truth["stars"]) {
          star |= std::hypot(s["x_px"].get<double>() - t["x_px"].get<double>(),
                             s["y_px"].get<double>() - t["y_px"].get<double>()) < 1.0;
        }
        ++(star ? found : spurious)[k];
      }
      ASSERT_EQ(Ssiu("solve " + f + ".png --camera " + c + " --json " + f + ".solve.json").status, 0);
      const Json r = ReadJsonFile(f + ".solve.json");
      if (r["status"] == "solved") matched[k] += static_cast<int>(r["matches"].size());
    }
  }
  std::printf(
      "stars found %d -> %d, spurious %d -> %d, matched %d -> %d (frame's PSF -> camera's); PSF assumed on %d of 6\n",
      found[0], found[1], spurious[0], spurious[1], matched[0], matched[1], assumed);
  EXPECT_GE(assumed, 1);
  EXPECT_GT(found[1], found[0] * 11 / 10);
  EXPECT_LE(spurious[1], spurious[0] + 3);
  EXPECT_GT(matched[1], matched[0] * 11 / 10);
  const Result flag = Ssiu("detect " + Path("f/frame_0000.png") + " --camera " + Path("cam_psf.json") +
                           " --psf-sigma-px 1.5 --json " + Path("flag.json"));
  ASSERT_EQ(flag.status, 0) << flag.output;
  EXPECT_EQ(ReadJsonFile(Path("flag.json"))["psf_sigma_px"], 1.5);
}

}  // namespace
}  // namespace ssiu
