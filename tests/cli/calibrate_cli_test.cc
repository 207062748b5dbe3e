// `ssiu calibrate` end to end: the real Swarm frames (../shared/data/swarm, pixels about twice as tall
// as wide) from a nominal guess, then every frame solved by `ssiu solve` with the written camera;
// bad input.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/camera.h"
#include "core/catalog.h"
#include "core/json.h"
#include "sim/frame_sim.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(CalibrateCli, SwarmFramesFromANominalGuessAllSolve) {
  SSIU_REQUIRE_SHARED(dir, "swarm");
  std::string frames;
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ".png") frames += " " + e.path().string(), ++n;
  ASSERT_GE(n, 10);
  const std::string tmp = testing::TempDir("calibrate_cli");
  // 20 mm lens, 8.6 um pixels, one video field: fx = 2326 px, fy about half (rows 2 x 8.6 um apart).
  std::ofstream(tmp + "/guess.json")
      << R"({"width": 752, "height": 290, "focal_length_mm": 20, "pixel_pitch_um": 8.6, "focal_length_y_px": 1163})";
  const std::string kstars = "/usr/share/kstars/stars.dat";
  const std::string source = std::ifstream(kstars) ? " --source " + kstars : "";
  const auto r = testing::RunSsiu("calibrate" + frames + " --camera " + tmp + "/guess.json --out " + tmp +
                                  "/cam.json --json " + tmp + "/report.json" + source);
  ASSERT_EQ(r.status, 0) << r.output;
  const Json rep = ReadJsonFile(tmp + "/report.json");
  EXPECT_EQ(rep["status"], "calibrated");
  EXPECT_EQ(rep["frames_solved"].get<int>(), n);
  const Camera cam = LoadCamera(tmp + "/cam.json");
  // Interline CCD read out as one field: fy/fx near 1/2 (8.6 um wide, ~2 x 8.3 um tall pixels).
  EXPECT_NEAR(cam.FocalYPx() / cam.focal_length_px, 0.5, 0.05);
  EXPECT_NEAR(cam.focal_length_px, 2325, 0.03 * 2325);
  EXPECT_LT(rep["held_out"]["rms_after_px"].get<double>(), rep["held_out"]["rms_before_px"].get<double>());
  EXPECT_LT(rep["rms_px"].get<double>(), 0.6);
  // Every frame solves with the written camera through `ssiu solve` (no focal tolerance).
  int solved = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() != ".png") continue;
    const auto s =
        testing::RunSsiu("solve " + e.path().string() + " --camera " + tmp + "/cam.json --json " + tmp + "/s.json");
    ASSERT_EQ(s.status, 0) << s.output;
    if (ReadJsonFile(tmp + "/s.json")["status"] == "solved") ++solved;
  }
  EXPECT_EQ(solved, n);
  // With square pixels (the guess without fy) `ssiu solve` solves none of them.
  std::ofstream(tmp + "/square.json")
      << R"({"width": 752, "height": 290, "focal_length_mm": 20, "pixel_pitch_um": 8.6})";
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() != ".png") continue;
    const auto s =
        testing::RunSsiu("solve " + e.path().string() + " --camera " + tmp + "/square.json --json " + tmp + "/s.json");
    EXPECT_NE(ReadJsonFile(tmp + "/s.json")["status"], "solved") << e.path();
    break;  // one is enough (an unsolvable frame searches its whole hypothesis budget)
  }
}

// Two heads, six simultaneous epochs as centroid CSVs: the second head's mount, 50 arcsec off its
// heads.json value, comes back within 3 sigma, and the written heads.json is a valid heads file.
TEST(CalibrateCli, HeadsWritesAlignedHeadsJson) {
  const std::string tmp = testing::TempDir("calibrate_cli_heads");
  const Camera cam = MakeCamera(1024, 1024, 16.6);
  const Quat nominal1(Eigen::AngleAxisd(kPi / 2, Vec3::UnitX()));
  const Vec3 off = Vec3(30, -20, 35) * kArcsecToRad;
  const Quat truth1 = nominal1 * Quat(Eigen::AngleAxisd(off.norm(), off.normalized()));
  const Quat mounts[2] = {Quat::Identity(), truth1};
  const StarCatalog sky = LoadXplanetBsc(DefaultBscPath(), 7.0);
  std::string frames;
  FrameSimOptions fo;
  DetectOptions d = SolveOptions{}.detect;
  d.gain_e_per_adu = fo.gain_e_per_adu;
  for (int e = 0; e < 6; ++e) {
    for (int h = 0; h < 2; ++h) {
      const SimulatedFrame sf = SimulateFrame(cam, sky, RandomAttitude(300 + e) * mounts[h], fo, 300 + 10 * e + h);
      const std::string path = tmp + "/e" + std::to_string(e) + "h" + std::to_string(h) + ".csv";
      std::ofstream csv(path);
      csv << "x_px,y_px,flux,sigma_px\n";
      for (const auto& c : CentroidsFromDetections(Detect(sf.image.view(), d), SolveOptions{}.detector_sigma_scale))
        csv << c.x_px << "," << c.y_px << "," << c.flux << "," << c.sigma_px << "\n";
      frames += " " + path;
    }
  }
  const auto q1 = ToWxyz(nominal1);
  Json cam1 = CameraToJson(cam);  // head 1's camera.json with a known hot pixel and a (weak) vignetting
  cam1["hot_pixels"] = {{3, 4}};
  cam1["vignetting"] = 0.05;
  WriteJsonFile(tmp + "/heads.json",
                Json::array({{{"camera", CameraToJson(cam)}, {"q_body_sensor", {1, 0, 0, 0}}},
                             {{"camera", cam1}, {"q_body_sensor", {q1[0], q1[1], q1[2], q1[3]}}}}));
  const auto r = testing::RunSsiu("calibrate" + frames + " --heads " + tmp + "/heads.json --out " + tmp +
                                  "/new.json --json " + tmp + "/rep.json --catalog " + tmp + "/cat --systematic-px 0");
  ASSERT_EQ(r.status, 0) << r.output;
  const Json out = ReadJsonFile(tmp + "/new.json"), rep = ReadJsonFile(tmp + "/rep.json");
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[1]["camera"]["hot_pixels"], cam1["hot_pixels"]);  // carried into the calibrated camera
  EXPECT_EQ(out[1]["camera"]["vignetting"], cam1["vignetting"]);
  EXPECT_FALSE(out[0]["camera"].contains("hot_pixels"));
  const Camera back = CameraFromJson(out[1]["camera"], "new.json");
  EXPECT_NEAR(back.focal_length_px, cam.focal_length_px, 0.002 * cam.focal_length_px);
  // The fitted cameras define slightly rotated sensor frames (a principal point error of 0.2 px turns
  // the frame by 0.2 / f): v_fit = D_h v_true, from a grid of pixels. The written mount must then be
  // M = D_0 M_1 D_1^T (head 0's mount is the identity), to within its reported sigma.
  auto frame_rotation = [&](const Camera& fitted) {
    Mat3 b = Mat3::Zero();
    for (double x = 0; x < 1024; x += 128)
      for (double y = 0; y < 1024; y += 128) b += fitted.Unproject(Vec2(x, y)) * cam.Unproject(Vec2(x, y)).transpose();
    Eigen::JacobiSVD<Mat3> svd(b, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Mat3 d = Mat3::Identity();
    d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant();
    return Mat3(svd.matrixU() * d * svd.matrixV().transpose());
  };
  const Mat3 d0 = frame_rotation(CameraFromJson(out[0]["camera"], "new.json")), d1 = frame_rotation(back);
  const Quat expected(Mat3(d0 * truth1.toRotationMatrix() * d1.transpose()));
  const Json& qj = out[1]["q_body_sensor"];
  const Quat est = FromWxyz(qj[0], qj[1], qj[2], qj[3]);
  std::printf("mount error against the truth %.1f arcsec, against the fitted cameras' frames %.2f arcsec\n",
              AttitudeErrorRad(est, truth1) * kRadToArcsec, AttitudeErrorRad(est, expected) * kRadToArcsec);
  Quat dq = expected.conjugate() * est;
  if (dq.w() < 0) dq.coeffs() = -dq.coeffs();
  const Vec3 err = 2 * dq.vec() * kRadToArcsec;
  const Json& sig = rep["heads"][1]["q_body_sensor_sigma_arcsec"];
  for (int a = 0; a < 3; ++a) {
    EXPECT_LT(std::abs(err[a]), 3 * sig[a].get<double>()) << "axis " << a << ": " << err.transpose();
    EXPECT_LT(sig[a].get<double>(), 5.0);
  }
  EXPECT_GE(rep["heads"][1]["alignment_epochs"].get<int>(), 4);  // epochs both heads solved
  const Json& q0 = out[0]["q_body_sensor"];
  EXPECT_EQ(q0[0].get<double>(), 1.0);  // head 0 keeps its mount
}

TEST(CalibrateCli, BadInputNamesTheFlagOrFile) {
  const std::string tmp = testing::TempDir("calibrate_cli_bad");
  auto r = testing::RunSsiu("calibrate " + tmp + "/none.png --out " + tmp + "/cam.json");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.output, ::testing::HasSubstr("--camera"));
  std::ofstream(tmp + "/bad.json")
      << R"({"width": 752, "height": 290, "focal_length_px": 2325, "focal_length_y_px": -3})";
  r = testing::RunSsiu("calibrate " + tmp + "/none.png --camera " + tmp + "/bad.json --out " + tmp + "/cam.json");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.output, ::testing::HasSubstr("focal_length_y_px"));
}

}  // namespace
}  // namespace ssiu
