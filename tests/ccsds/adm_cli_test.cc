// The `ssiu` program with CCSDS attitude messages: `fuse --st` from an ACM/AEM equals the CSV run, and
// `--aem/--acm` outputs read back to what the run printed, valid against the official schemas.
#include <fitsio.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "ccsds/adm.h"
#include "core/attitude.h"
#include "core/csv.h"
#include "core/image.h"
#include "core/json.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

constexpr double kBiasXDph = 2.0;

// A body turning at 0.05 deg/s about z: gyro body rates at 10 Hz (with a bias on x), star-tracker
// attitudes at 1 Hz with their sigmas, over 60 s. The CSV files and the same attitudes as a history.
struct Scene {
  std::string dir;
  AttitudeHistory st;
};

Scene MakeScene(const std::string& name) {
  Scene s;
  s.dir = testing::TempDir(name);
  const double w_rad_s = 0.05 * kDegToRad;
  const Quat q0 = QuatFromRaDecRoll(40 * kDegToRad, 10 * kDegToRad, 0.2);
  auto q_at = [&](double t) { return q0 * Quat(Eigen::AngleAxisd(w_rad_s * t, Vec3::UnitZ())); };
  std::ofstream g(s.dir + "/gyro.csv");
  g << "t_s,wx_dph,wy_dph,wz_dph\n";
  for (int k = 1; k <= 600; ++k) g << k * 0.1 << "," << kBiasXDph << ",0," << w_rad_s * kRadSToDph << "\n";
  std::ofstream st(s.dir + "/st.csv");
  st << "t_s,qw,qx,qy,qz,sigma_cross_arcsec,sigma_roll_arcsec\n";
  s.st.epoch_utc = "2025-06-21T10:00:00";
  s.st.body_frame = "AST_1";
  s.st.cov_type = "ANGLE";
  char b[256];
  for (int k = 0; k <= 60; ++k) {
    const auto q = ToWxyz(q_at(k));
    std::snprintf(b, sizeof b, "%d,%.12f,%.12f,%.12f,%.12f,5,30\n", k, q[0], q[1], q[2], q[3]);
    st << b;
    AdmState a;
    a.t_s = k;
    a.q_inertial_from_body = FromWxyz(q[0], q[1], q[2], q[3]);
    s.st.states.push_back(a);
    const double c = std::pow(5 * kArcsecToRad, 2), r = std::pow(30 * kArcsecToRad, 2);
    s.st.covariances.push_back({static_cast<double>(k), {c, c, r}});
  }
  return s;
}

std::vector<std::vector<double>> Columns(const std::string& csv) {
  const CsvTable t = ReadCsv(csv);
  std::vector<std::vector<double>> c;
  for (const auto& h : t.header) c.push_back(t.Column(h));
  return c;
}

void ExpectSameCsv(const std::string& a, const std::string& b) {
  const auto x = Columns(a), y = Columns(b);
  ASSERT_EQ(x.size(), y.size());
  for (size_t i = 0; i < x.size(); ++i) {
    ASSERT_EQ(x[i].size(), y[i].size());
    for (size_t k = 0; k < x[i].size(); ++k)
      EXPECT_NEAR(x[i][k], y[i][k], 1e-9 * (1 + std::abs(x[i][k]))) << i << "," << k;
  }
}

TEST(AdmCli, FuseFromAnAcmEqualsFuseFromTheSameHistoryAsCsv) {
  const Scene s = MakeScene("adm_cli_fuse_from");
  WriteAdmFile(s.dir + "/st.acm", s.st, AdmMessage::kAcm);
  WriteAdmFile(s.dir + "/st_acm.xml", s.st, AdmMessage::kAcm);
  AttitudeHistory no_cov = s.st;
  no_cov.covariances.clear();
  no_cov.cov_type.clear();
  WriteAdmFile(s.dir + "/st.aem", no_cov, AdmMessage::kAem);
  const std::string fuse = "fuse --gyro " + s.dir + "/gyro.csv --no-fdi ";
  testing::SsiuResult r = testing::RunSsiu(fuse + "--st " + s.dir + "/st.csv --out " + s.dir + "/csv.csv");
  ASSERT_EQ(r.status, 0) << r.output;
  for (const std::string st : {"st.acm", "st_acm.xml"}) {
    r = testing::RunSsiu(fuse + "--st " + s.dir + "/" + st + " --out " + s.dir + "/" + st + ".csv");
    ASSERT_EQ(r.status, 0) << r.output;
    SCOPED_TRACE(st);
    ExpectSameCsv(s.dir + "/csv.csv", s.dir + "/" + st + ".csv");
  }
  // An AEM carries no sigmas: the same as the CSV without its sigma columns (the options' 5 / 30 arcsec).
  r = testing::RunSsiu(fuse + "--st " + s.dir + "/st.aem --epoch-utc 2025-06-21T10:00:00Z --out " + s.dir + "/aem.csv");
  ASSERT_EQ(r.status, 0) << r.output;
  ExpectSameCsv(s.dir + "/csv.csv", s.dir + "/aem.csv");
}

TEST(AdmCli, FuseWritesAemAndAcmThatReadBackToTheRun) {
  const Scene s = MakeScene("adm_cli_fuse_to");
  const std::string fuse = "fuse --gyro " + s.dir + "/gyro.csv --st " + s.dir + "/st.csv --no-fdi ";
  // Without a time of day the messages cannot be written: one line naming the flag.
  testing::SsiuResult r = testing::RunSsiu(fuse + "--acm " + s.dir + "/x.acm");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.output, HasSubstr("--epoch-utc"));
  const std::string run =
      fuse + "--epoch-utc 2025-06-21T10:00:00Z --out " + s.dir + "/f.csv --json " + s.dir + "/f.json ";
  r = testing::RunSsiu(run + "--aem " + s.dir + "/f.aem --acm " + s.dir + "/f.acm");
  ASSERT_EQ(r.status, 0) << r.output;
  r = testing::RunSsiu(run + "--aem " + s.dir + "/f_aem.xml --acm " + s.dir + "/f_acm.xml");
  ASSERT_EQ(r.status, 0) << r.output;
  const CsvTable out = ReadCsv(s.dir + "/f.csv");
  const AttitudeHistory acm = ReadAdmFile(s.dir + "/f.acm"), acm_xml = ReadAdmFile(s.dir + "/f_acm.xml");
  const AttitudeHistory aem = ReadAdmFile(s.dir + "/f.aem", "2025-06-21T10:00:00");
  ASSERT_EQ(acm.states.size(), out.rows());
  ASSERT_EQ(aem.states.size(), out.rows());
  EXPECT_EQ(acm.epoch_utc, "2025-06-21T10:00:00.000000");
  EXPECT_EQ(acm.cov_type, "ANGLE_GYROBIAS");
  ASSERT_EQ(acm.covariances.size(), out.rows());
  for (size_t k = 0; k < out.rows(); k += 37) {
    const Quat q = FromWxyz(out.Column("qw")[k], out.Column("qx")[k], out.Column("qy")[k], out.Column("qz")[k]);
    EXPECT_NEAR(acm.states[k].t_s, out.Column("t_s")[k], 1e-6);
    EXPECT_NEAR(aem.states[k].t_s, out.Column("t_s")[k], 1e-6);
    EXPECT_THAT(acm.states[k].q_inertial_from_body, QuaternionNear(q, 1e-4));
    EXPECT_THAT(aem.states[k].q_inertial_from_body, QuaternionNear(q, 1e-4));
    EXPECT_NEAR(acm.states[k].gyro_bias_rad_s->x() * kRadSToDph, out.Column("bx_dph")[k], 1e-6);
    EXPECT_NEAR(std::sqrt(acm.covariances[k].diagonal[2]) * kRadToArcsec, out.Column("sigma_z_arcsec")[k], 1e-4);
    // KVN and XML of one run: the same numbers
    EXPECT_EQ(acm.states[k].q_inertial_from_body.coeffs(), acm_xml.states[k].q_inertial_from_body.coeffs());
    EXPECT_EQ(acm.covariances[k].diagonal, acm_xml.covariances[k].diagonal);
  }
  // The angular velocity is the scene's 0.05 deg/s about z once the bias is removed.
  ASSERT_TRUE(acm.has_rates());
  ASSERT_TRUE(aem.has_rates());
  EXPECT_LT((*acm.states.back().w_body_rad_s - Vec3(0, 0, 0.05 * kDegToRad)).norm(), 0.2 * kDphToRadS);
  EXPECT_LT((*aem.states.back().w_body_rad_s - *acm.states.back().w_body_rad_s).norm(), 1e-12);
  // The filter found the bias it was given (the truth of the scene).
  EXPECT_NEAR(acm.states.back().gyro_bias_rad_s->x() * kRadSToDph, kBiasXDph, 0.2);
  ASSERT_TRUE(acm.determination.has_value());
  EXPECT_EQ(acm.determination->method, "EKF");
  const Json j = ReadJsonFile(s.dir + "/f.json");
  EXPECT_NEAR(acm.determination->sigma_v_rad_s05, j["noise"]["arw_deg_per_sqrt_h"].get<double>() / 60 * kDegToRad,
              1e-15);
  ASSERT_EQ(acm.determination->sensors.size(), 2u);
  EXPECT_NEAR(acm.determination->sensors[0].rate_hz, 1.0, 1e-9);   // the star tracker at 1 Hz
  EXPECT_NEAR(acm.determination->sensors[1].rate_hz, 10.0, 1e-6);  // the gyros at 10 Hz
  EXPECT_NEAR(acm.determination->sensors[0].noise_sigma_rad[2] * kRadToArcsec, 30.0, 1e-6);
  // The XML validates against the official schemas (skipped without ../shared or xmllint).
  const std::string xsd = testing::SharedData("ccsds/xsd/ndmxml-4.0.0-master-4.0.xsd");
  std::string msg;
  if (xsd.empty() || testing::Run("command -v xmllint", &msg) != 0)
    GTEST_SKIP() << "no ../shared schemas or no xmllint";
  for (const std::string f : {"f_aem.xml", "f_acm.xml"})
    EXPECT_EQ(testing::Run("xmllint --noout --nonet --schema '" + xsd + "' '" + s.dir + "/" + f + "' 2>&1", &msg), 0)
        << msg;
}

TEST(AdmCli, BadMessageIsOneLineNamingFileLineKeyword) {
  const Scene s = MakeScene("adm_cli_bad");
  std::string text = FormatAdm(s.st, AdmMessage::kAcm, false);
  text.replace(text.find("NUMBER_STATES"), 13, "NUMBER_STATEZ");
  std::ofstream(s.dir + "/bad.acm") << text;
  const testing::SsiuResult r = testing::RunSsiu("fuse --gyro " + s.dir + "/gyro.csv --st " + s.dir + "/bad.acm");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.output, ::testing::MatchesRegex(".*bad\\.acm:[0-9]+: NUMBER_STATEZ: not an ATT keyword\n"));
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
}

// `ssiu run` on a tiny mission: the ACM's attitudes are the simulated truth within their covariance.
TEST(AdmCli, RunWritesTheFusedAttitudeAgainstTheTruth) {
  const std::string d = testing::TempDir("adm_cli_run");
  std::ofstream(d + "/ssiu.json")
      << R"({"seed": 2, "duration_s": 12, "frame_rate_hz": 0.5, "score_after_s": 4, "start_utc": "2025-03-01T12:00:00Z",)"
      << R"("heads": [{"camera": {"width": 384, "height": 384, "focal_length_px": 1316}, "q_body_sensor": [1, 0, 0, 0]}]})";
  const testing::SsiuResult r = testing::RunSsiu("run --config " + d + "/ssiu.json --out " + d + "/out --acm " + d +
                                                 "/run_acm.xml --aem " + d + "/run.aem");
  ASSERT_EQ(r.status, 0) << r.output;
  const AttitudeHistory acm = ReadAdmFile(d + "/run_acm.xml");
  const AttitudeHistory aem = ReadAdmFile(d + "/run.aem", "2025-03-01T12:00:00");
  EXPECT_EQ(acm.epoch_utc, "2025-03-01T12:00:00.000000");
  EXPECT_EQ(acm.basis, "SIMULATED");
  ASSERT_GT(acm.states.size(), 100u);
  ASSERT_EQ(aem.states.size(), acm.states.size());
  const CsvTable truth = ReadCsv(d + "/out/attitude.csv");
  ASSERT_EQ(truth.rows(), acm.states.size());
  int within = 0;
  for (size_t k = 0; k < truth.rows(); ++k) {
    EXPECT_NEAR(acm.states[k].t_s, truth.Column("t_s")[k], 1e-6);
    EXPECT_NEAR(aem.states[k].t_s, truth.Column("t_s")[k], 1e-6);
    const Quat q_true = FromWxyz(truth.Column("true_qw")[k], truth.Column("true_qx")[k], truth.Column("true_qy")[k],
                                 truth.Column("true_qz")[k]);
    const Quat dq = q_true.conjugate() * acm.states[k].q_inertial_from_body;
    const Vec3 e = 2 * dq.vec() * (dq.w() < 0 ? -1 : 1);
    for (int i = 0; i < 3; ++i) within += std::abs(e[i]) <= 3 * std::sqrt(acm.covariances[k].diagonal[i]);
  }
  EXPECT_GT(within, 0.95 * 3 * truth.rows());
  ASSERT_TRUE(acm.determination.has_value());
  EXPECT_EQ(acm.determination->sensors.size(), 2u);  // one head and the gyros
  EXPECT_EQ(acm.determination->sensors[0].used, "AST_1");
  EXPECT_NEAR(acm.determination->sensors[0].rate_hz, 0.5, 1e-9);
  const std::string xsd = testing::SharedData("ccsds/xsd/ndmxml-4.0.0-master-4.0.xsd");
  std::string msg;
  if (xsd.empty() || testing::Run("command -v xmllint", &msg) != 0)
    GTEST_SKIP() << "no ../shared schemas or no xmllint";
  EXPECT_EQ(testing::Run("xmllint --noout --nonet --schema '" + xsd + "' '" + d + "/run_acm.xml' 2>&1", &msg), 0)
      << msg;
}

// Frames with their own times: a batch `ssiu solve` of FITS frames (DATE-OBS) and `ssiu track` (--time,
// --dt-s) write the solved attitudes at those times, each the simulated truth within its covariance.
void ExpectSameDigits(const AttitudeHistory& a, const AttitudeHistory& b) {
  ASSERT_EQ(a.states.size(), b.states.size());
  for (size_t k = 0; k < a.states.size(); ++k) {
    EXPECT_EQ(a.states[k].t_s, b.states[k].t_s);
    EXPECT_EQ(a.states[k].q_inertial_from_body.coeffs(), b.states[k].q_inertial_from_body.coeffs());
    EXPECT_EQ(a.covariances[k].diagonal, b.covariances[k].diagonal);
  }
}

TEST(AdmCli, SolveAndTrackWriteTheSolutionsAtTheFrameTimes) {
  const std::string d = testing::TempDir("adm_cli_solve");
  std::ofstream(d + "/cam.json") << R"({"width": 384, "height": 384, "focal_length_px": 1316})";
  testing::SsiuResult r = testing::RunSsiu("simulate frame --camera " + d +
                                           "/cam.json --ra-deg 80 --dec-deg 20 "
                                           "--roll-deg 10 --seed 5 --count 3 --out " +
                                           d + "/f");
  ASSERT_EQ(r.status, 0) << r.output;
  const char* dates[] = {"2030-01-05T03:00:05", "2030-01-05T03:00:00", "2030-01-05T03:00:02.5"};  // out of order
  std::string fits_list;
  for (int k = 0; k < 3; ++k) {
    char name[64];
    std::snprintf(name, sizeof name, "/f/frame_%04d", k);
    const std::string fits = d + name + ".fits";
    WriteFits16(fits, ReadFrame(d + name + ".png").image);
    fitsfile* f = nullptr;
    int status = 0;
    std::string value = dates[k];
    fits_open_file(&f, fits.c_str(), READWRITE, &status);
    fits_update_key(f, TSTRING, "DATE-OBS", &value[0], "UTC", &status);
    fits_close_file(f, &status);
    ASSERT_EQ(status, 0);
    fits_list += " " + fits;
  }
  const Json truth = ReadJsonFile(d + "/f/frame_0000.json");
  const Quat q_true = FromWxyz(truth["q"][0], truth["q"][1], truth["q"][2], truth["q"][3]);
  auto check = [&](const AttitudeHistory& h, const std::vector<double>& t_s) {
    ASSERT_EQ(h.states.size(), t_s.size());
    EXPECT_EQ(h.body_frame, "AST_1");
    ASSERT_TRUE(h.determination.has_value());
    EXPECT_EQ(h.determination->method, "QUEST");
    for (size_t k = 0; k < t_s.size(); ++k) {
      EXPECT_NEAR(h.states[k].t_s, t_s[k], 1e-6);
      const Quat dq = q_true.conjugate() * h.states[k].q_inertial_from_body;
      const Vec3 e = 2 * dq.vec() * (dq.w() < 0 ? -1 : 1);  // sensor axes
      for (int i = 0; i < 3; ++i)
        EXPECT_LT(std::abs(e[i]), 4 * std::sqrt(h.covariances[k].diagonal[i])) << k << " " << i;
    }
  };
  const std::string common = " --camera " + d + "/cam.json --catalog " + d + "/cat ";
  r = testing::RunSsiu("solve" + fits_list + common + "--jsonl " + d + "/s.jsonl --acm " + d + "/s.acm --aem " + d +
                       "/s_aem.xml");
  ASSERT_EQ(r.status, 0) << r.output;
  const AttitudeHistory s = ReadAdmFile(d + "/s.acm");
  EXPECT_EQ(s.epoch_utc, "2030-01-05T03:00:00.000000");
  check(s, {0.0, 2.5, 5.0});
  EXPECT_NEAR(s.determination->sensors[0].rate_hz, 0.4, 1e-9);  // median interval 2.5 s
  EXPECT_EQ(ReadAdmFile(d + "/s_aem.xml").states.size(), 3u);
  // One time for every frame is not a history: refused, naming the flag.
  r = testing::RunSsiu("solve" + fits_list + common + "--time 2030-01-05T03:00:00Z --jsonl " + d + "/t.jsonl --acm " +
                       d + "/t.acm");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.output, HasSubstr("--aem/--acm: two solved frames at the same time"));
  // track: the first frame's time and the interval.
  r = testing::RunSsiu("track " + d + "/f/frame_0000.png " + d + "/f/frame_0001.png " + d + "/f/frame_0002.png" +
                       common + "--time 2030-01-05T03:00:00Z --dt-s 0.5 --json " + d + "/tr.json --acm " + d +
                       "/tr.acm");
  ASSERT_EQ(r.status, 0) << r.output;
  check(ReadAdmFile(d + "/tr.acm"), {0.0, 0.5, 1.0});
  // Without a time there is no history to write: one line naming the flags.
  r = testing::RunSsiu("track " + d + "/f/frame_0000.png" + common + "--json " + d + "/tr2.json --aem " + d +
                       "/tr2.aem");
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.output, HasSubstr("--aem/--acm: a solved frame has no time"));
  const std::string xsd = testing::SharedData("ccsds/xsd/ndmxml-4.0.0-master-4.0.xsd");
  std::string msg;
  if (xsd.empty() || testing::Run("command -v xmllint", &msg) != 0)
    GTEST_SKIP() << "no ../shared schemas or no xmllint";
  r = testing::RunSsiu("solve" + fits_list + common + "--jsonl " + d + "/s2.jsonl --acm " + d + "/s_acm.xml");
  ASSERT_EQ(r.status, 0) << r.output;
  ExpectSameDigits(s, ReadAdmFile(d + "/s_acm.xml"));  // KVN and XML of the same solutions
  for (const std::string f : {"s_aem.xml", "s_acm.xml"})
    EXPECT_EQ(testing::Run("xmllint --noout --nonet --schema '" + xsd + "' '" + d + "/" + f + "' 2>&1", &msg), 0)
        << msg;
}

}  // namespace
}  // namespace ssiu
