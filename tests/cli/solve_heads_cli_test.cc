// `ssiu solve --heads HEADS.json F1 F2 [F3]` end to end: frames simulated for a known body attitude
// and known mounts (heads.json as in conventions.md), fused body attitude against the truth, the
// JSON contract of `ssiu solve`, a blind head, and bad heads files.
#include <cmath>
#include <fstream>
#include <string>

#include "core/attitude.h"
#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using Result = testing::SsiuResult;
Result Ssiu(const std::string& args) { return testing::RunSsiu(args); }
Quat QuatOf(const Json& q) { return FromWxyz(q[0], q[1], q[2], q[3]); }

class SolveHeadsCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(testing::TempDir("solve_heads_cli"));
    build_status_ = Ssiu("catalog build --fov-deg 16.6 --out " + *dir_ + "/cat").status;
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string Path(const std::string& n) { return *dir_ + "/" + n; }

  // Simulates head `name`'s frame for body attitude q_body and mount (sensor -> body); returns the
  // frame path. extra: more `simulate frame` flags.
  static std::string SimulateHead(const std::string& name, const Quat& q_body, const Quat& mount, int seed,
                                  const std::string& extra = "") {
    const RaDecRoll a = RaDecRollFromQuat(q_body * mount);
    char args[512];
    std::snprintf(
        args, sizeof args, "simulate frame --ra-deg %.10f --dec-deg %.10f --roll-deg %.10f --seed %d %s --out %s",
        a.ra_rad * kRadToDeg, a.dec_rad * kRadToDeg, a.roll_rad * kRadToDeg, seed, extra.c_str(), Path(name).c_str());
    const Result r = Ssiu(args);
    EXPECT_EQ(r.status, 0) << r.output;
    return Path(name + "/frame_0000.png");
  }
  static Json Head(const Quat& mount) {
    const auto q = ToWxyz(mount);
    return {{"camera", ReadJsonFile(Path("h0/camera.json"))}, {"q_body_sensor", {q[0], q[1], q[2], q[3]}}};
  }
  static std::string* dir_;
  static int build_status_;
};
std::string* SolveHeadsCli::dir_ = nullptr;
int SolveHeadsCli::build_status_ = -1;

const Quat kM0 = Quat::Identity();
const Quat kM1(Eigen::AngleAxisd(kPi / 2, Vec3::UnitX()));
const Quat kM2(Eigen::AngleAxisd(kPi / 2, Vec3::UnitY()));

TEST_F(SolveHeadsCli, TwoAndThreeHeadsFuseToTheBodyAttitude) {
  ASSERT_EQ(build_status_, 0);
  const Quat q_body = QuatFromRaDecRoll(200 * kDegToRad, -35 * kDegToRad, 75 * kDegToRad);
  const std::string f0 = SimulateHead("h0", q_body, kM0, 11), f1 = SimulateHead("h1", q_body, kM1, 12),
                    f2 = SimulateHead("h2", q_body, kM2, 13);
  // The truth of head 0 (identity mount) is the body attitude as the simulator wrote it.
  const Quat truth = QuatOf(ReadJsonFile(Path("h0/frame_0000.json"))["q"]);
  ASSERT_THAT(truth, QuaternionNear(q_body, 0.01));
  WriteJsonFile(Path("heads2.json"), Json::array({Head(kM0), Head(kM1)}));
  WriteJsonFile(Path("heads3.json"), Json::array({Head(kM0), Head(kM1), Head(kM2)}));

  Result r = Ssiu("solve " + f0 + " --camera " + Path("h0/camera.json") + " --catalog " + Path("cat") + " --json " +
                  Path("one.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Json one = ReadJsonFile(Path("one.json"));
  ASSERT_EQ(one["status"], "solved");
  const double single_roll_sigma = one["sigma_roll_arcsec"].get<double>();

  for (const std::string n : {"2", "3"}) {
    r = Ssiu("solve --heads " + Path("heads" + n + ".json") + " " + f0 + " " + f1 + (n == "3" ? " " + f2 : "") +
             " --catalog " + Path("cat") + " --json " + Path("fused" + n + ".json"));
    ASSERT_EQ(r.status, 0) << r.output;
    const Json s = ReadJsonFile(Path("fused" + n + ".json"));
    for (const char* k : {"status", "q", "ra_deg", "dec_deg", "roll_deg", "sigma_cross_arcsec", "sigma_roll_arcsec",
                          "focal_length_px", "false_match_probability", "matches", "timing_ms", "heads"}) {
      EXPECT_TRUE(s.contains(k)) << n << " heads: " << k;
    }
    ASSERT_EQ(s["status"], "solved") << s.dump();
    EXPECT_EQ(s["frame"], "body");
    EXPECT_GE(s["q"][0].get<double>(), 0.0);
    ASSERT_EQ(s["heads"].size(), n == "3" ? 3u : 2u);
    for (const auto& h : s["heads"]) EXPECT_EQ(h["use"], "used");
    const double sc = s["sigma_cross_arcsec"].get<double>(), sr = s["sigma_roll_arcsec"].get<double>();
    const double err = AttitudeErrorRad(QuatOf(s["q"]), truth) * kRadToArcsec;
    std::printf("%s heads: error %.2f arcsec, sigma cross %.2f roll %.2f (single head roll %.2f)\n", n.c_str(), err, sc,
                sr, single_roll_sigma);
    // Within a few sigma of the reported covariance (sc, sr per axis; 3-D error ~ sqrt(3) sigma).
    EXPECT_LT(err, 4 * std::sqrt(2 * sc * sc + sr * sr)) << n << " heads";
    EXPECT_LT(sr, single_roll_sigma / 4) << n << " heads";
    EXPECT_GT(s["matches"].size(), 20u);
    for (const char* k : {"head", "x_px", "y_px", "star_id", "mag", "residual_arcsec"})
      EXPECT_TRUE(s["matches"][0].contains(k)) << k;
  }

  // A blind head (no stars in its frame) is reported and left out; the other two still give the attitude.
  const std::string blind = SimulateHead("hb", q_body, kM2, 14, "--mag-max -5");
  r = Ssiu("solve --heads " + Path("heads3.json") + " " + f0 + " " + f1 + " " + blind + " --catalog " + Path("cat") +
           " --json " + Path("blind.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  const Json b = ReadJsonFile(Path("blind.json"));
  ASSERT_EQ(b["status"], "solved");
  EXPECT_NE(b["heads"][2]["use"], "used");
  EXPECT_NE(b["heads"][2]["status"], "solved");
  EXPECT_LT(AttitudeErrorRad(QuatOf(b["q"]), truth) * kRadToArcsec, 10.0);
}

TEST_F(SolveHeadsCli, BadHeadsFilesAreOneLineErrors) {
  ASSERT_EQ(build_status_, 0);
  const std::string f0 = SimulateHead("e0", Quat::Identity(), kM0, 21);
  const Json cam = ReadJsonFile(Path("e0/camera.json"));
  // Two heads listed, one frame given.
  WriteJsonFile(Path("two.json"), Json::array({{{"camera", cam}, {"q_body_sensor", {1, 0, 0, 0}}},
                                               {{"camera", cam}, {"q_body_sensor", {1, 0, 0, 0}}}}));
  Result r = Ssiu("solve --heads " + Path("two.json") + " " + f0 + " --catalog " + Path("cat"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, ::testing::HasSubstr("two.json"));
  // No mount quaternion.
  WriteJsonFile(Path("nomount.json"), Json::array({{{"camera", cam}}}));
  r = Ssiu("solve --heads " + Path("nomount.json") + " " + f0 + " --catalog " + Path("cat"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, ::testing::HasSubstr("q_body_sensor"));
  // A zero quaternion.
  WriteJsonFile(Path("zero.json"), Json::array({{{"camera", cam}, {"q_body_sensor", {0, 0, 0, 0}}}}));
  r = Ssiu("solve --heads " + Path("zero.json") + " " + f0 + " --catalog " + Path("cat"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, ::testing::HasSubstr("q_body_sensor"));
  // Four heads: at most three.
  Json four = Json::array();
  for (int i = 0; i < 4; ++i) four.push_back({{"camera", cam}, {"q_body_sensor", {1, 0, 0, 0}}});
  WriteJsonFile(Path("four.json"), four);
  r = Ssiu("solve --heads " + Path("four.json") + " " + f0 + " " + f0 + " " + f0 + " " + f0 + " --catalog " +
           Path("cat"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, ::testing::HasSubstr("four.json"));
}

// A head's camera.json vignetting is taken out of that head's fluxes as `ssiu solve` does for one camera:
// frames simulated with vignetting 0.6 give each head stronger photometric evidence when its camera
// states it.
TEST_F(SolveHeadsCli, EachHeadsVignettingIsTakenOut) {
  ASSERT_EQ(build_status_, 0);
  const Quat q_body = QuatFromRaDecRoll(120 * kDegToRad, 25 * kDegToRad, 40 * kDegToRad);
  const std::string f0 = SimulateHead("v0", q_body, kM0, 21, "--vignetting 0.6"),
                    f1 = SimulateHead("v1", q_body, kM1, 22, "--vignetting 0.6");
  const auto q1 = ToWxyz(kM1);
  const Json cam = ReadJsonFile(Path("v0/camera.json"));
  Json plain = Json::array({{{"camera", cam}, {"q_body_sensor", {1, 0, 0, 0}}},
                            {{"camera", cam}, {"q_body_sensor", {q1[0], q1[1], q1[2], q1[3]}}}}),
       stated = plain;
  for (auto& h : stated) h["camera"]["vignetting"] = 0.6;
  WriteJsonFile(Path("vplain.json"), plain);
  WriteJsonFile(Path("vstated.json"), stated);
  double ln_factor[2][2];
  int k = 0;
  for (const char* heads : {"vplain.json", "vstated.json"}) {
    const Result r = Ssiu("solve --heads " + Path(heads) + " " + f0 + " " + f1 + " --catalog " + Path("cat") +
                          " --json " + Path("v.json"));
    ASSERT_EQ(r.status, 0) << r.output;
    const Json s = ReadJsonFile(Path("v.json"));
    ASSERT_EQ(s["status"], "solved") << heads;
    for (int h = 0; h < 2; ++h) {
      ASSERT_EQ(s["heads"][h]["status"], "solved") << heads << " head " << h;
      ln_factor[k][h] = std::log(s["heads"][h]["photometric_factor"].get<double>());
    }
    ++k;
  }
  std::printf("ln photometric factor, heads 0 and 1: vignetting left in %.1f %.1f, stated %.1f %.1f\n", ln_factor[0][0],
              ln_factor[0][1], ln_factor[1][0], ln_factor[1][1]);
  for (int h = 0; h < 2; ++h) EXPECT_LT(ln_factor[1][h], ln_factor[0][h]) << "head " << h;
}

}  // namespace
}  // namespace ssiu
