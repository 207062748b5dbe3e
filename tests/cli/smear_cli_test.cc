// `--rate-dps` / `--exposure-s` of `ssiu detect`, `ssiu solve` and `ssiu track` end to end: a frame
// simulated while the sensor turns at 2 deg/s (a 12 px smear on the default 1024 px camera over the
// 0.1 s exposure) is detected and solved against the simulator's truth with and without the rate,
// and bad flags exit 1 with one line.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "core/attitude.h"
#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;
using Result = testing::SsiuResult;
Result Ssiu(const std::string& args) { return testing::RunSsiu(args); }

Quat QuatOf(const Json& q) { return FromWxyz(q[0], q[1], q[2], q[3]); }

// The simulator's rate (sensor axes) and the flags that tell the detector about it.
constexpr const char* kSimRate = "--rate-x-dps 2 --rate-y-dps 0.5 --rate-z-dps 0";
constexpr const char* kRateFlags = " --rate-dps 2,0.5,0 --exposure-s 0.1";

// Truth stars with SNR >= 20, unsaturated and 10 px inside the frame, found within 2 px.
struct Recall {
  int truth = 0, found = 0;
  double rms_px = 0;  // over the found ones
};
Recall Score(const Json& truth, const Json& det) {
  Recall r;
  const double w = truth["camera"]["width"].get<double>(), h = truth["camera"]["height"].get<double>();
  double sum2 = 0;
  for (const auto& s : truth["stars"]) {
    const double x = s["x_px"].get<double>(), y = s["y_px"].get<double>();
    if (s["snr"].get<double>() < 20 || s["saturated"].get<bool>() || x < 10 || y < 10 || x > w - 11 || y > h - 11) {
      continue;
    }
    ++r.truth;
    double best = 1e9;
    for (const auto& d : det["stars"])
      best = std::min(best, std::hypot(d["x_px"].get<double>() - x, d["y_px"].get<double>() - y));
    if (best < 2.0) {
      ++r.found;
      sum2 += best * best;
    }
  }
  r.rms_px = r.found ? std::sqrt(sum2 / r.found) : 0;
  return r;
}

class SmearCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(testing::TempDir("smear_cli"));
    sim_ = new Result(Ssiu("simulate frame --ra-deg 83.8 --dec-deg -5.4 --roll-deg 10 --seed 4 " +
                           std::string(kSimRate) + " --out " + Path("f")));
    cat_ = new Result(Ssiu("catalog build --fov-deg 16.6 --out " + Path("cat")));
  }
  static void TearDownTestSuite() {
    delete dir_;
    delete sim_;
    delete cat_;
  }
  void SetUp() override {
    ASSERT_EQ(sim_->status, 0) << sim_->output;
    ASSERT_EQ(cat_->status, 0) << cat_->output;
  }
  static std::string Path(const std::string& n) { return *dir_ + "/" + n; }
  static std::string Frame() { return Path("f/frame_0000.png"); }
  static std::string Camera() { return " --camera " + Path("f/camera.json"); }
  // Exit 1 with exactly one line holding `needle`.
  static void ExpectBadInput(const std::string& args, const std::string& needle) {
    const Result r = Ssiu(args);
    EXPECT_EQ(r.status, 1) << args << "\n" << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_THAT(r.output, HasSubstr("ssiu: error: "));
    EXPECT_THAT(r.output, HasSubstr(needle)) << args;
  }
  static std::string* dir_;
  static Result* sim_;
  static Result* cat_;
};
std::string* SmearCli::dir_ = nullptr;
Result* SmearCli::sim_ = nullptr;
Result* SmearCli::cat_ = nullptr;

TEST_F(SmearCli, DetectWithTheRateFindsAndCentroidsTheSmearedStars) {
  const Json truth = ReadJsonFile(Path("f/frame_0000.json"));
  ASSERT_GT(truth["stars"][0]["smear_px"].get<double>(), 10.0);  // the frame is smeared (12.6 px)
  ASSERT_EQ(Ssiu("detect " + Frame() + Camera() + " --json " + Path("still.json")).status, 0);
  const Result r = Ssiu("detect " + Frame() + Camera() + kRateFlags + " --json " + Path("moving.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Json moving = ReadJsonFile(Path("moving.json"));
  const Recall a = Score(truth, ReadJsonFile(Path("still.json"))), b = Score(truth, moving);
  // Measured: still fit 20 of 52 within 2 px (RMS 1.40 px), smeared fit 48 of 52 (RMS 0.21 px).
  ASSERT_GT(a.truth, 30);
  EXPECT_GE(b.found, 0.85 * b.truth) << b.found << " of " << b.truth;
  EXPECT_LE(a.found, 0.6 * a.truth) << a.found << " of " << a.truth;
  EXPECT_LT(b.rms_px, 0.4);
  EXPECT_GT(a.rms_px, 2 * b.rms_px);
  // The model used is reported.
  ASSERT_TRUE(moving.contains("smear_model"));
  EXPECT_NEAR(moving["smear_model"]["rate_dps"][0].get<double>(), 2.0, 1e-12);
  EXPECT_NEAR(moving["smear_model"]["exposure_s"].get<double>(), 0.1, 1e-12);
}

TEST_F(SmearCli, SolveWithTheRateHasASmallerAttitudeError) {
  const Quat q_true = QuatOf(ReadJsonFile(Path("f/frame_0000.json"))["q"]);
  const std::string base = "solve " + Frame() + Camera() + " --catalog " + Path("cat");
  ASSERT_EQ(Ssiu(base + " --json " + Path("still.json")).status, 0);
  const Result r = Ssiu(base + kRateFlags + " --json " + Path("moving.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Json still = ReadJsonFile(Path("still.json")), moving = ReadJsonFile(Path("moving.json"));
  ASSERT_EQ(moving["status"], "solved");
  const double e_moving = AttitudeErrorRad(QuatOf(moving["q"]), q_true) * kRadToArcsec;
  // Measured on seeds 4-6: 95-164 arcsec without the rate, 1.4-12 arcsec with it.
  EXPECT_LT(e_moving, 20.0);
  if (still["status"] == "solved") {
    EXPECT_GT(AttitudeErrorRad(QuatOf(still["q"]), q_true) * kRadToArcsec, 3 * e_moving + 30);
    EXPECT_GT(moving["matches"].size(), still["matches"].size() + 5);
  }
}

TEST_F(SmearCli, TrackWithTheRateFollowsASmearedSequence) {
  // Three frames 0.2 deg apart, each smeared by the same rate; the first is the suite's frame.
  for (int k = 1; k < 3; ++k) {
    ASSERT_EQ(
        Ssiu("simulate frame --ra-deg " + std::to_string(83.8 + 0.2 * k) + " --dec-deg -5.4 --roll-deg 10 --seed " +
             std::to_string(4 + k) + " " + kSimRate + " --out " + Path("t" + std::to_string(k)))
            .status,
        0);
  }
  const std::string frames = Frame() + " " + Path("t1/frame_0000.png") + " " + Path("t2/frame_0000.png");
  const Result r =
      Ssiu("track " + frames + Camera() + " --catalog " + Path("cat") + kRateFlags + " --json " + Path("t.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Json t = ReadJsonFile(Path("t.json"));
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t[2]["mode"], "tracking");
  for (int k = 0; k < 3; ++k) {
    ASSERT_EQ(t[k]["status"], "solved") << k;
    const std::string truth = k == 0 ? Path("f/frame_0000.json") : Path("t" + std::to_string(k) + "/frame_0000.json");
    // Measured: 4.2, 3.2, 10.9 arcsec with the rate; 130, 149, 70 arcsec without it.
    const Quat q_true = QuatOf(ReadJsonFile(truth)["q"]);
    EXPECT_LT(AttitudeErrorRad(QuatOf(t[k]["q"]), q_true) * kRadToArcsec, 25.0) << k;
    EXPECT_LT(SplitAttitudeError(QuatOf(t[k]["q"]), q_true).cross_rad * kRadToArcsec, 10.0) << k;
  }
}

TEST_F(SmearCli, SolveHeadsTurnsTheBodyRateIntoEachHeadsAxes) {
  // Head 0 along the body, head 1 turned 90 deg about body X: a body rate (2, 0.5, 0) deg/s is
  // (2, 0, -0.5) deg/s in head 1's axes. Each head is simulated with its own rate; --rate-dps gives
  // the body rate once.
  const Quat q_body = QuatFromRaDecRoll(200 * kDegToRad, -35 * kDegToRad, 75 * kDegToRad);
  const Quat mounts[2] = {Quat::Identity(), Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitX()))};
  const Vec3 w_body_dps(2, 0.5, 0);
  Json heads = Json::array();
  std::string frames;
  for (int h = 0; h < 2; ++h) {
    const Vec3 w = mounts[h].conjugate() * w_body_dps;
    const RaDecRoll a = RaDecRollFromQuat(q_body * mounts[h]);
    char args[512];
    std::snprintf(args, sizeof args,
                  "simulate frame --ra-deg %.10f --dec-deg %.10f --roll-deg %.10f --seed %d --rate-x-dps %.12f "
                  "--rate-y-dps %.12f --rate-z-dps %.12f --out %s",
                  a.ra_rad * kRadToDeg, a.dec_rad * kRadToDeg, a.roll_rad * kRadToDeg, 11 + h, w.x(), w.y(), w.z(),
                  Path("h" + std::to_string(h)).c_str());
    ASSERT_EQ(Ssiu(args).status, 0);
    const auto q = ToWxyz(mounts[h]);
    heads.push_back({{"camera", ReadJsonFile(Path("h0/camera.json"))}, {"q_body_sensor", {q[0], q[1], q[2], q[3]}}});
    frames += " " + Path("h" + std::to_string(h) + "/frame_0000.png");
  }
  WriteJsonFile(Path("heads.json"), heads);
  const std::string base = "solve --heads " + Path("heads.json") + frames + " --catalog " + Path("cat");
  ASSERT_EQ(Ssiu(base + " --json " + Path("hs.json")).status, 0);
  const Result r = Ssiu(base + kRateFlags + " --json " + Path("hm.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Json still = ReadJsonFile(Path("hs.json")), moving = ReadJsonFile(Path("hm.json"));
  ASSERT_EQ(moving["status"], "solved");
  EXPECT_THAT(QuatOf(moving["q"]), QuaternionNear(q_body, 15.0));
  // Head 1 matches clearly more stars only if its smear was predicted in its own axes.
  for (int h = 0; h < 2; ++h) {
    EXPECT_GT(moving["heads"][h]["matches"].size(), still["heads"][h]["matches"].size() + 5) << "head " << h;
  }
}

TEST_F(SmearCli, BadRateFlagsExitOneWithOneLine) {
  const std::string det = "detect " + Frame() + " --json -";
  ExpectBadInput(det + Camera() + " --rate-dps nan,0,0 --exposure-s 0.1", "--rate-dps: 'nan' is not a finite");
  ExpectBadInput(det + Camera() + " --rate-dps 1,inf,0 --exposure-s 0.1", "--rate-dps: 'inf' is not a finite");
  ExpectBadInput(det + Camera() + " --rate-dps 0x10,0,0 --exposure-s 0.1", "'0x10' is not a finite decimal");
  ExpectBadInput(det + Camera() + " --rate-dps 2,0.5 --exposure-s 0.1",
                 "--rate-dps: needs three components X,Y,Z (deg/s), got 2");
  ExpectBadInput(det + Camera() + " --rate-dps 2,0.5,0, --exposure-s 0.1", "--rate-dps: an empty component");
  ExpectBadInput(det + Camera() + " --rate-dps 2,0.5,0 --exposure-s -0.1",
                 "--exposure-s: must be a finite number in (0, 100)");
  ExpectBadInput(det + Camera() + " --rate-dps 2,0.5,0 --exposure-s nan", "--exposure-s: must be a finite number");
  ExpectBadInput(det + " --rate-dps 2,0.5,0 --exposure-s 0.1", "--rate-dps: needs --camera");
  ExpectBadInput(det + Camera() + " --rate-dps 2,0.5,0", "--exposure-s: required with --rate-dps");
  ExpectBadInput(det + Camera() + " --exposure-s 0.1", "--exposure-s: given without --rate-dps");
  // 100 deg/s would smear by 627 px here: refused, not a minute of fitting.
  ExpectBadInput(det + Camera() + " --rate-dps 100,0,0 --exposure-s 0.1", "smear by up to 627 px");
  ExpectBadInput(det + Camera() + " --rate-dps 0,0,1e6 --exposure-s 0.1", "--rate-dps: with --exposure-s 0.1");
  // solve: the same checks; a centroid list has no smear to model.
  const std::string solve = "solve " + Frame() + Camera() + " --catalog " + Path("cat");
  ExpectBadInput(solve + " --rate-dps nan,0,0 --exposure-s 0.1", "--rate-dps: 'nan'");
  ExpectBadInput(solve + " --rate-dps 1,2 --exposure-s 0.1", "got 2");
  ExpectBadInput(solve + " --rate-dps 1,2,0 --exposure-s -1", "--exposure-s: must be");
  std::ofstream(Path("c.csv")) << "x_px,y_px\n1,2\n";
  ExpectBadInput("solve --centroids " + Path("c.csv") + Camera() + " --catalog " + Path("cat") + kRateFlags,
                 "--rate-dps: needs a frame, not --centroids");
  // track
  const std::string track = "track " + Frame() + Camera() + " --catalog " + Path("cat");
  ExpectBadInput(track + " --rate-dps inf,0,0 --exposure-s 0.1", "--rate-dps: 'inf'");
  ExpectBadInput(track + " --rate-dps 1,0,0", "--exposure-s: required");
}

}  // namespace
}  // namespace ssiu
