// `ssiu groundtest mask | simulate | reference | compare` end to end, and bad input -> exit 1.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <utility>
#include <vector>

#include "core/csv.h"
#include "core/json.h"
#include "core/types.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

class GroundtestCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::TempDir("groundtest_cli");
    std::ofstream(dir_ + "/cam.json") << R"({"width": 1024, "height": 1024, "focal_length_px": 3510.0})";
    std::ofstream(dir_ + "/other.json") << R"({"width": 1024, "height": 1024, "focal_length_px": 2500.0})";
    ASSERT_EQ(Ssiu("groundtest mask --camera " + dir_ +
                   "/cam.json --collimator-focal-mm 500 --ra-deg 83.8 --dec-deg -1 "
                   "--roll-deg 20 --dpi 100 --out " +
                   dir_ + "/mask --catalog " + dir_ + "/cat"),
              0)
        << out_;
  }
  int Ssiu(const std::string& args) { return testing::Run(testing::SsiuProgram() + " " + args, &out_); }
  std::string dir_, out_;
};

// A slow slew on the stand (`--slew`): the pictures step evenly across the field, every one solves,
// and `ssiu performance` reads the sequence against the stand's truth (truth.csv, what an ideal
// tracker reports): the tracker's errors at the level its pixel scale allows (59 arcsec/px at
// f = 3510 px: a twentieth of a pixel a star, ~60 stars).
TEST_F(GroundtestCli, SlewSequenceFeedsThePerformanceReport) {
  if (testing::kUnderSanitizer)
    GTEST_SKIP() << "64 rendered pictures (too long for the sanitizer run's share of CI time); the same simulation, "
                    "solving and reading "
                    "run there in GroundtestCli.MaskSimulateReferenceCompareRecoverTheMisalignment, the report in "
                    "PerformanceCli.JsonContractAndPlots";
  const std::string sim = dir_ + "/slew";
  ASSERT_EQ(Ssiu("groundtest simulate --mask " + dir_ + "/mask/mask.json --slew --positions 64 --max-angle-deg 6 "
                 "--step-s 10 --seed 3 --solve --catalog " + dir_ + "/cat --out " + sim),
            0)
      << out_;
  const Json t = ReadJsonFile(sim + "/truth.json");
  ASSERT_EQ(t["pictures"].size(), 64u);
  for (size_t i = 0; i < 64; ++i) {
    const double f = 2.0 * static_cast<double>(i) / 63 - 1;
    EXPECT_NEAR(t["pictures"][i]["az_deg"].get<double>(), 6 * f, 1e-9);
    EXPECT_NEAR(t["pictures"][i]["el_deg"].get<double>(), 3 * f, 1e-9);
    EXPECT_EQ(t["pictures"][i]["rot_deg"].get<double>(), 0.0);
  }
  const CsvTable computed = ReadCsv(sim + "/computed.csv");
  EXPECT_EQ(computed.rows(), 64u);
  ASSERT_EQ(Ssiu("performance --measured " + sim + "/computed.csv --reference " + sim + "/truth.csv --camera " + sim +
                 "/camera.json --json " + dir_ + "/perf.json"),
            0)
      << out_;
  const Json p = ReadJsonFile(dir_ + "/perf.json");
  for (int k = 0; k < 2; ++k) {
    EXPECT_LT(std::abs(p["bias_arcsec"][k].get<double>()), 1.0) << k;
    EXPECT_LT(p["total_sigma_arcsec"][k].get<double>(), 2.0) << k;
    EXPECT_GT(p["total_sigma_arcsec"][k].get<double>(), 0.0) << k;
  }
  EXPECT_LT(p["total_sigma_arcsec"][2].get<double>(), 20.0);
}

TEST_F(GroundtestCli, MaskSimulateReferenceCompareRecoverTheMisalignment) {
  const Json mask = ReadJsonFile(dir_ + "/mask/mask.json");
  EXPECT_GT(mask["holes"].size(), 50u);
  EXPECT_EQ(mask["tags"].size(), 8u);
  EXPECT_EQ(mask["tag_family"], "tag36h11");
  EXPECT_DOUBLE_EQ(mask["png_dpi"].get<double>(), 100.0);
  std::ifstream svg(dir_ + "/mask/mask.svg");
  EXPECT_TRUE(svg.good());
  const std::string sim = dir_ + "/sim";
  ASSERT_EQ(Ssiu("groundtest simulate --mask " + dir_ + "/mask/mask.json --camera " + dir_ +
                 "/cam.json --positions 4 --misalignment-arcmin 2,-3,5 --seed 4 --solve --catalog " + dir_ +
                 "/cat --out " + sim),
            0)
      << out_;
  ASSERT_EQ(
      Ssiu("groundtest reference --mask " + dir_ + "/mask/mask.json --encoders " + sim + "/encoders.csv --photos " +
           sim + "/photo_000.png " + sim + "/photo_001.png " + sim + "/photo_002.png " + sim +
           "/photo_003.png --aux-camera " + sim + "/aux_camera.json --out " + dir_ + "/ref.csv"),
      0)
      << out_;
  ASSERT_EQ(Ssiu("groundtest compare --reference " + dir_ + "/ref.csv --computed " + sim + "/computed.csv --json " +
                 dir_ + "/cmp.json --plot " + dir_ + "/plots --requirement-arcsec 6"),
            0)
      << out_;
  const Json c = ReadJsonFile(dir_ + "/cmp.json");
  EXPECT_EQ(c["pictures"], 4);
  const double truth[3] = {120, -180, 300};
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(c["misalignment_arcsec"][k].get<double>(), truth[k],
                3 * c["misalignment_sigma_arcsec"][k].get<double>())
        << "axis " << k;
  EXPECT_TRUE(c["pass"].get<bool>()) << c["verdict"];
  EXPECT_TRUE(std::ifstream(dir_ + "/plots/errors.png").good());
  EXPECT_TRUE(std::ifstream(dir_ + "/plots/residuals.png").good());
  // Encoders only: the plate is taken as nominal, so its offset (truth.json's mask rotation, small
  // stand angles: about the same in tracker axes) ends up in the misalignment, with the opposite sign.
  ASSERT_EQ(Ssiu("groundtest reference --mask " + dir_ + "/mask/mask.json --encoders " + sim + "/encoders.csv --out " +
                 dir_ + "/ref_enc.csv"),
            0)
      << out_;
  ASSERT_EQ(Ssiu("groundtest compare --reference " + dir_ + "/ref_enc.csv --computed " + sim + "/computed.csv --json " +
                 dir_ + "/cmp_enc.json"),
            0)
      << out_;
  const Json ce = ReadJsonFile(dir_ + "/cmp_enc.json");
  const Json t = ReadJsonFile(sim + "/truth.json");
  for (int k = 0; k < 3; ++k) {
    const double expected = truth[k] - t["mask_rotation_arcsec"][k].get<double>();
    EXPECT_NEAR(ce["misalignment_arcsec"][k].get<double>(), expected,
                3 * ce["misalignment_sigma_arcsec"][k].get<double>() + 3)
        << "axis " << k << " (plate rotation " << t["mask_rotation_arcsec"][k] << ")";
  }
}

TEST_F(GroundtestCli, BadInputExitsOneWithAReason) {
  const std::string m = dir_ + "/mask/mask.json";
  // A mask designed for another camera.
  EXPECT_EQ(
      Ssiu("groundtest simulate --mask " + m + " --camera " + dir_ + "/other.json --positions 1 --out " + dir_ + "/x"),
      1);
  EXPECT_THAT(out_, ::testing::HasSubstr("designed for another camera"));
  // No fiducials on the photo; then the wrong family.
  ASSERT_EQ(Ssiu("groundtest simulate --mask " + m + " --positions 1 --photo-hide-tags --out " + dir_ + "/blank"), 0)
      << out_;
  EXPECT_EQ(Ssiu("groundtest reference --mask " + m + " --photos " + dir_ + "/blank/photo_000.png --aux-camera " +
                 dir_ + "/blank/aux_camera.json --out " + dir_ + "/r.csv"),
            1);
  EXPECT_THAT(out_, ::testing::HasSubstr("no tag36h11 fiducials visible"));
  EXPECT_EQ(std::count(out_.begin(), out_.end(), '\n'), 1) << out_;
  ASSERT_EQ(
      Ssiu("groundtest simulate --mask " + m + " --positions 1 --photo-tag-family tag25h9 --out " + dir_ + "/fam"), 0)
      << out_;
  EXPECT_EQ(Ssiu("groundtest reference --mask " + m + " --photos " + dir_ + "/fam/photo_000.png --aux-camera " + dir_ +
                 "/fam/aux_camera.json --out " + dir_ + "/r.csv"),
            1);
  EXPECT_THAT(out_, ::testing::HasSubstr("wrong tag family"));
  // A design attitude off the sky: used to give a mask of every catalog star (NaN RA) or of a
  // declination past the pole, with exit 0.
  for (const std::string att :
       {"--ra-deg nan --dec-deg 0", "--ra-deg 10 --dec-deg 100", "--ra-deg 10 --dec-deg 0 --roll-deg inf"}) {
    EXPECT_EQ(Ssiu("groundtest mask --camera " + dir_ + "/other.json --collimator-focal-mm 500 " + att + " --out " +
                   dir_ + "/m2"),
              1)
        << att << "\n"
        << out_;
    EXPECT_THAT(out_, ::testing::HasSubstr("--dec-deg in [-90, 90]")) << att;
    EXPECT_EQ(std::count(out_.begin(), out_.end(), '\n'), 1) << out_;
  }
  // Compare: a tracker log without a quaternion column.
  std::ofstream(dir_ + "/bad.csv") << "t_s,qw,qx,qy\n0,1,0,0\n1,1,0,0\n";
  std::ofstream(dir_ + "/ok.csv") << "t_s,qw,qx,qy,qz\n0,1,0,0,0\n1,1,0,0,0\n";
  EXPECT_EQ(Ssiu("groundtest compare --reference " + dir_ + "/ok.csv --computed " + dir_ + "/bad.csv"), 1);
  EXPECT_THAT(out_, ::testing::HasSubstr("qz"));
  // Encoders with a NaN, a missing column, time going backwards: each names the file and the column.
  auto reference_with = [&](const std::string& name, const std::string& csv) {
    std::ofstream(dir_ + "/" + name) << csv;
    const int status =
        Ssiu("groundtest reference --mask " + m + " --encoders " + dir_ + "/" + name + " --out " + dir_ + "/r.csv");
    EXPECT_THAT(out_, ::testing::HasSubstr(name)) << name;
    EXPECT_EQ(std::count(out_.begin(), out_.end(), '\n'), 1) << out_;
    return status;
  };
  EXPECT_EQ(reference_with("enc_nan.csv", "t_s,az_deg,el_deg,rot_deg\n0,0,0,0\n1,nan,0,0\n"), 1);
  EXPECT_THAT(out_, ::testing::HasSubstr("az_deg"));
  EXPECT_EQ(reference_with("enc_cols.csv", "t_s,az_deg,el_deg\n0,0,0\n1,0.1,0\n"), 1);
  EXPECT_THAT(out_, ::testing::HasSubstr("rot_deg"));
  EXPECT_EQ(reference_with("enc_time.csv", "t_s,az_deg,el_deg,rot_deg\n0,0,0,0\n60,0.1,0,0\n30,0.2,0,0\n"), 1);
  EXPECT_THAT(out_, ::testing::HasSubstr("t_s"));
  EXPECT_EQ(reference_with("enc_empty.csv", "t_s,az_deg,el_deg,rot_deg\n"), 1);
  EXPECT_EQ(reference_with("enc_turns.csv", "t_s,az_deg,el_deg,rot_deg\n0,0,0,0\n1,1e300,0,0\n"), 1);
  EXPECT_THAT(out_, ::testing::HasSubstr("row 2: encoder angle beyond +-360 deg"));
  // A 1-sigma of 1e300 arcsec made the fit's weights 0/0 (NaN misalignment, exit 0).
  std::ofstream(dir_ + "/huge_sigma.csv")
      << "t_s,qw,qx,qy,qz,sigma_cross_arcsec,sigma_roll_arcsec\n0,1,0,0,0,1e300,5\n1,1,0,0,0,1e300,5\n";
  EXPECT_EQ(Ssiu("groundtest compare --reference " + dir_ + "/ok.csv --computed " + dir_ + "/huge_sigma.csv"), 1)
      << out_;
  EXPECT_THAT(out_, ::testing::HasSubstr("huge_sigma.csv: sigma columns"));
  // The mask checked against another tracker camera by `reference` too.
  EXPECT_EQ(Ssiu("groundtest reference --mask " + m + " --camera " + dir_ + "/other.json --encoders " + dir_ +
                 "/enc_time.csv --out " + dir_ + "/r.csv"),
            1);
  EXPECT_THAT(out_, ::testing::HasSubstr("mask.json: designed for another camera"));
  // Reference and tracker logs whose times do not match (another session's log).
  std::ofstream(dir_ + "/late.csv") << "t_s,qw,qx,qy,qz\n500,1,0,0,0\n560,1,0,0,0\n620,1,0,0,0\n";
  EXPECT_EQ(Ssiu("groundtest compare --reference " + dir_ + "/ok.csv --computed " + dir_ + "/late.csv"), 1);
  EXPECT_THAT(out_, ::testing::HasSubstr("late.csv: 0 picture(s) matched a reference time"));
  EXPECT_EQ(std::count(out_.begin(), out_.end(), '\n'), 1) << out_;
  // A tracker log with time going backwards.
  std::ofstream(dir_ + "/back.csv") << "t_s,qw,qx,qy,qz\n1,1,0,0,0\n0,1,0,0,0\n";
  EXPECT_EQ(Ssiu("groundtest compare --reference " + dir_ + "/ok.csv --computed " + dir_ + "/back.csv"), 1);
  EXPECT_THAT(out_, ::testing::HasSubstr("back.csv"));
  // A NaN plate shift gave a NaN plate pose and frames of nothing (exit 0).
  for (const auto& [flag, field] :
       std::vector<std::pair<std::string, std::string>>{{"--plate-shift-mm nan", "plate_shift_mm"},
                                                        {"--plate-shift-mm 1e9", "plate_shift_mm"},
                                                        {"--plate-turn-deg inf", "plate_turn_deg"}}) {
    EXPECT_EQ(Ssiu("groundtest simulate --mask " + m + " --positions 1 " + flag + " --out " + dir_ + "/p"), 1) << flag;
    EXPECT_THAT(out_, ::testing::HasSubstr("stand options: " + field + " must be within")) << flag;
    EXPECT_EQ(std::count(out_.begin(), out_.end(), '\n'), 1) << out_;
  }
  // A 1e9 mm hole overflowed the renderer's int window size (UBSan); now refused with its size.
  Json big = ReadJsonFile(m);
  big["holes"][0]["diameter_mm"] = 1e9;
  WriteJsonFile(dir_ + "/big_hole.json", big);
  EXPECT_EQ(Ssiu("groundtest simulate --mask " + dir_ + "/big_hole.json --positions 1 --out " + dir_ + "/p"), 1)
      << out_;
  EXPECT_THAT(out_, ::testing::HasSubstr("diameter_mm 1e+09 images to a radius of 3.51e+09 px at the tracker"));
  EXPECT_EQ(std::count(out_.begin(), out_.end(), '\n'), 1) << out_;
}

}  // namespace
}  // namespace ssiu
