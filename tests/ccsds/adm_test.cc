// CCSDS ADM 2.0 writing and reading: the quaternion convention against the standard's definition and
// conventions.md, round trips in both encodings, the official samples and schemas.
#include "ccsds/adm.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "core/attitude.h"
#include "core/error.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

std::string Slurp(const std::string& path) {
  std::ifstream f(path);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

// A history with a known slew: boresight moving in RA at 0.1 deg/s, gyro bias and covariance.
AttitudeHistory Slew(bool rates, bool bias, bool cov) {
  AttitudeHistory h;
  h.epoch_utc = "2025-06-21T00:00:00Z";
  h.object_name = "TEST";
  for (int k = 0; k < 20; ++k) {
    AdmState s;
    s.t_s = 0.5 * k + 0.125;
    s.q_inertial_from_body = QuatFromRaDecRoll((30 + 0.05 * k) * kDegToRad, -20 * kDegToRad, 0.3 + 0.001 * k);
    if (rates) s.w_body_rad_s = Vec3(1e-4 * k, -2e-3, 1.745e-3);
    if (bias) s.gyro_bias_rad_s = Vec3(3e-7, -1e-6, 2.5e-6 + 1e-8 * k);
    h.states.push_back(s);
    if (cov) {
      AdmCovariance c;
      c.t_s = s.t_s;
      const double a = std::pow(5 * kArcsecToRad, 2), b = std::pow(0.01 * kDphToRadS, 2);
      c.diagonal = {a, a * 1.1, a * 30};
      if (bias) c.diagonal.insert(c.diagonal.end(), {b, b, b * 2});
      h.covariances.push_back(c);
    }
  }
  if (cov) h.cov_type = bias ? "ANGLE_GYROBIAS" : "ANGLE";
  AdmDetermination d;
  d.method = "EKF";
  d.sigma_u_rad_s15 = 1e-9;
  d.sigma_v_rad_s05 = 3e-6;
  d.sensors.push_back({1, "AST_1", {5 * kArcsecToRad, 5 * kArcsecToRad, 30 * kArcsecToRad}, 2.0});
  d.sensors.push_back({2, "GYRO", {}, 100.0});
  h.determination = d;
  return h;
}

void ExpectSameHistory(const AttitudeHistory& a, const AttitudeHistory& b) {
  ASSERT_EQ(a.states.size(), b.states.size());
  for (size_t k = 0; k < a.states.size(); ++k) {
    const AdmState &x = a.states[k], &y = b.states[k];
    EXPECT_NEAR(x.t_s, y.t_s, 1e-6) << k;  // printed to 1 microsecond
    EXPECT_THAT(x.q_inertial_from_body, QuaternionNear(y.q_inertial_from_body, 1e-6));
    ASSERT_EQ(x.w_body_rad_s.has_value(), y.w_body_rad_s.has_value());
    if (x.w_body_rad_s) {
      EXPECT_LT((*x.w_body_rad_s - *y.w_body_rad_s).norm(), 1e-9 * x.w_body_rad_s->norm() + 1e-15);
    }
    ASSERT_EQ(x.gyro_bias_rad_s.has_value(), y.gyro_bias_rad_s.has_value());
    if (x.gyro_bias_rad_s) {
      EXPECT_LT((*x.gyro_bias_rad_s - *y.gyro_bias_rad_s).norm(), 1e-9 * x.gyro_bias_rad_s->norm());
    }
  }
  ASSERT_EQ(a.covariances.size(), b.covariances.size());
  EXPECT_EQ(a.cov_type, b.cov_type);
  for (size_t k = 0; k < a.covariances.size(); ++k) {
    EXPECT_NEAR(a.covariances[k].t_s, b.covariances[k].t_s, 1e-6);
    ASSERT_EQ(a.covariances[k].diagonal.size(), b.covariances[k].diagonal.size());
    for (size_t i = 0; i < a.covariances[k].diagonal.size(); ++i)
      EXPECT_NEAR(a.covariances[k].diagonal[i], b.covariances[k].diagonal[i], 1e-9 * a.covariances[k].diagonal[i]);
  }
}

// 504.0-B-2's quaternion (Q1 Q2 Q3 vector, QC scalar) rotates REF_FRAME_A into REF_FRAME_B: the frame
// transformation v_B = A(q) v_A with A(q) = (qc^2 - |e|^2) I + 2 e e^T - 2 qc [e x] (the standard's
// attitude matrix, written here independently of the library). ssiu's q_inertial_from_body takes body
// vectors to inertial (conventions.md), so A(q_adm) must take inertial vectors to body.
TEST(AdmConvention, QuaternionOrderAndDirectionAsTheStandardDefines) {
  // Body +X points to inertial +Y: a rotation by +90 deg about Z, body -> inertial.
  const Quat q = Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitZ()));
  ASSERT_LT((q * Vec3::UnitX() - Vec3::UnitY()).norm(), 1e-12);
  AttitudeHistory h;
  h.epoch_utc = "2025-01-01T00:00:00";
  h.states.push_back({0.0, q, {}, {}});
  const std::string kvn = FormatAdm(h, AdmMessage::kAem, false, "2025-01-01T00:00:00");
  const size_t at = kvn.find("2025-01-01T00:00:00.000000 ", kvn.find("DATA_START"));
  ASSERT_NE(at, std::string::npos) << kvn;
  double q1, q2, q3, qc;
  ASSERT_EQ(std::sscanf(kvn.c_str() + at + 27, "%lf %lf %lf %lf", &q1, &q2, &q3, &qc), 4);
  const Vec3 e(q1, q2, q3);
  Mat3 ex;
  ex << 0, -e.z(), e.y(), e.z(), 0, -e.x(), -e.y(), e.x(), 0;
  const Mat3 a = (qc * qc - e.squaredNorm()) * Mat3::Identity() + 2 * e * e.transpose() - 2 * qc * ex;
  EXPECT_LT((a * Vec3::UnitY() - Vec3::UnitX()).norm(), 1e-9) << "inertial +Y must be body +X";
  EXPECT_NEAR(qc, std::sqrt(0.5), 1e-12);  // scalar last
  EXPECT_NEAR(q3, std::sqrt(0.5), 1e-12);
}

// conventions.md is the contract this mapping rests on: scalar-first Hamilton, sensor/body -> inertial.
TEST(AdmConvention, ConventionsDocumentStatesWhatTheMappingAssumes) {
  const std::string shared = testing::SharedDir();
  const std::string path = shared + "/docs/conventions.md";
  if (shared.empty() || !std::filesystem::exists(path)) GTEST_SKIP() << "../shared/docs/conventions.md not found";
  const std::string text = Slurp(path);
  EXPECT_NE(text.find("scalar first `[w, x, y, z]`"), std::string::npos);
  EXPECT_NE(text.find("FROM the sensor frame TO the inertial frame"), std::string::npos);
  EXPECT_NE(text.find("v_inertial = q * v_sensor * conj(q)"), std::string::npos);
}

TEST(AdmRoundTrip, EveryMessageAndEncodingReadsBackWithinPrintedPrecision) {
  for (bool rates : {false, true})
    for (bool bias : {false, true})
      for (AdmMessage m : {AdmMessage::kAem, AdmMessage::kAcm}) {
        const AttitudeHistory h = Slew(rates, bias && m == AdmMessage::kAcm, m == AdmMessage::kAcm);
        const AttitudeHistory kvn = ParseAdm(FormatAdm(h, m, false), "mem.kvn", h.epoch_utc);
        const AttitudeHistory xml = ParseAdm(FormatAdm(h, m, true), "mem.xml", h.epoch_utc);
        SCOPED_TRACE(std::string(m == AdmMessage::kAem ? "AEM" : "ACM") + (rates ? " rates" : "") +
                     (bias ? " bias" : ""));
        ExpectSameHistory(h, kvn);
        ExpectSameHistory(kvn, xml);
        // read -> write -> read: nothing moves beyond the printed digits
        ExpectSameHistory(kvn, ParseAdm(FormatAdm(kvn, m, false), "again.kvn", h.epoch_utc));
        if (m == AdmMessage::kAcm) {
          ASSERT_TRUE(xml.determination.has_value());
          EXPECT_EQ(xml.determination->method, "EKF");
          EXPECT_NEAR(xml.determination->sigma_u_rad_s15, 1e-9, 1e-18);
          EXPECT_NEAR(xml.determination->sigma_v_rad_s05, 3e-6, 1e-15);
          ASSERT_EQ(xml.determination->sensors.size(), 2u);
          EXPECT_EQ(xml.determination->sensors[0].used, "AST_1");
          EXPECT_NEAR(xml.determination->sensors[0].noise_sigma_rad[2], 30 * kArcsecToRad, 1e-15);
          EXPECT_DOUBLE_EQ(xml.determination->sensors[1].rate_hz, 100.0);
        }
      }
}

TEST(AdmRoundTrip, KvnAndXmlCarryTheSameDigits) {
  const AttitudeHistory h = Slew(true, true, true);
  for (AdmMessage m : {AdmMessage::kAem, AdmMessage::kAcm}) {
    const std::string kvn = FormatAdm(h, m, false, "2025-01-01T00:00:00"),
                      xml = FormatAdm(h, m, true, "2025-01-01T00:00:00");
    // every number token of the KVN data appears in the XML
    std::istringstream is(kvn);
    std::string tok;
    int n = 0;
    while (is >> tok)
      if (tok.find_first_of("0123456789") == 0 || tok[0] == '-') {
        EXPECT_NE(xml.find(tok), std::string::npos) << tok;
        ++n;
      }
    EXPECT_GT(n, 100);
  }
}

TEST(AdmTime, EpochsAcrossTimeSystemsAndALeapSecond) {
  // 2016-12-31T23:59:60 UTC was a leap second: 2 SI seconds from 23:59:59 to 2017-01-01T00:00:00.
  EXPECT_NEAR(AdmSecondsSince("2017-01-01T00:00:00", "UTC", "2016-12-31T23:59:59", "t"), 2.0, 1e-9);
  EXPECT_EQ(AdmEpoch("2016-12-31T23:59:59", 1.5), "2016-12-31T23:59:60.500000");
  // TAI - UTC = 37 s in 2020; day-of-year form.
  EXPECT_NEAR(AdmSecondsSince("2020-032T00:00:37", "TAI", "2020-02-01T00:00:00", "t"), 0.0, 1e-9);
  EXPECT_NEAR(AdmSecondsSince("2020-02-01T00:00:18", "GPS", "2020-02-01T00:00:00", "t"), 0.0, 1e-9);
  EXPECT_THAT(
      testing::ErrorOf([] { AdmSecondsSince("2020-02-31T00:00:00", "UTC", "2020-01-01T00:00:00", "F:3: EPOCH"); }),
      ::testing::HasSubstr("F:3: EPOCH"));
}

TEST(AdmRead, ErrorsNameFileLineAndKeyword) {
  const AttitudeHistory h = Slew(false, false, false);
  std::string kvn = FormatAdm(h, AdmMessage::kAem, false);
  const std::string bad = std::string(kvn).replace(kvn.find("QUATERNION"), 10, "EULER_ANGLE");
  EXPECT_THAT(testing::ErrorOf([&] { ParseAdm(bad, "x.aem"); }),
              ::testing::MatchesRegex("x\\.aem:[0-9]+: ATTITUDE_TYPE: .*"));
  std::string typo = kvn;
  typo.replace(typo.find("OBJECT_ID"), 9, "OBJECT_IDX");
  EXPECT_THAT(testing::ErrorOf([&] { ParseAdm(typo, "x.aem"); }),
              ::testing::MatchesRegex("x\\.aem:[0-9]+: OBJECT_IDX: .*"));
  std::string num = kvn;
  num.insert(num.find(' ', num.find("DATA_START") + 11) + 1, "x");
  EXPECT_THAT(testing::ErrorOf([&] { ParseAdm(num, "x.aem"); }), ::testing::MatchesRegex("x\\.aem:[0-9]+: DATA: 'x.*"));
  std::string xml = FormatAdm(h, AdmMessage::kAem, true);
  xml.replace(xml.find("</QC>"), 5, "</Q4>");
  EXPECT_THAT(testing::ErrorOf([&] { ParseAdm(xml, "x.xml"); }), ::testing::MatchesRegex("x\\.xml:[0-9]+: XML: .*"));
  AttitudeHistory no_epoch = h;
  no_epoch.epoch_utc.clear();
  EXPECT_THAT(testing::ErrorOf([&] { FormatAdm(no_epoch, AdmMessage::kAem, false); }), ::testing::HasSubstr("epoch"));
}

}  // namespace
}  // namespace ssiu
namespace ssiu {
namespace {

std::vector<std::string> SampleFiles(const std::string& dir) {
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.is_regular_file()) files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

std::string Escaped(const std::string& s) {
  std::string r;
  for (char c : s) {
    if (std::string(".[]()*+?^$|\\{}").find(c) != std::string::npos) r += '\\';
    r += c;
  }
  return r;
}

// The quaternion histories among the samples (ADM 2.0 and 1.0, KVN and XML) are read; the rest is
// refused with one line naming the file, the line and the keyword.
TEST(AdmSamples, QuaternionHistoriesAreReadTheRestRefusedWithFileLineKeyword) {
  SSIU_REQUIRE_SHARED(dir, "ccsds/samples");
  const std::map<std::string, size_t> must_read = {
      {"jmaene_acm_g6.kvn", 3},
      {"jmaene_adm_g12.xml", 1},
      {"orbitformats_golden_aem.xml", 4},
      {"orekit-acm_ACMExample01.txt", 3},
      {"orekit-acm_ACMExample02.txt", 4},
      {"orekit-acm_ACMExample05.txt", 2},
      {"orekit-acm_ACM-frame-mapper.txt", 2},
      // ADM 1.0 KVN (QUATERNION_TYPE, ATTITUDE_DIR)
      {"orbitformats_golden_aem.aem", 4},
      {"gmat_QuaternionFile.aem", 8},
      {"orekit-aem_AEMExample01.txt", 8},
      {"orekit-aem_AEMExample02.txt", 4},
      {"orekit-aem_AEMExample04.txt", 13},
      {"orekit-aem_AEMExample07.txt", 3},
      {"orekit-aem_AEMExample10.txt", 8},
      {"gmat_CCSDS_BasicQuatFile.aem", 123}};  // two segments sharing their boundary epoch (124 lines)
  size_t read = 0, refused = 0;
  for (const std::string& f : SampleFiles(dir)) {
    const std::string name = std::filesystem::path(f).filename().string();
    SCOPED_TRACE(name);
    std::string error;
    AttitudeHistory h;
    try {
      h = ReadAdmFile(f);
    } catch (const InputError& e) {
      error = e.what();
    }
    const auto m = must_read.find(name);
    if (m != must_read.end()) {
      EXPECT_EQ(error, "");
      EXPECT_EQ(h.states.size(), m->second);
    }
    if (error.empty()) {
      ++read;
      for (const AdmState& s : h.states) EXPECT_NEAR(s.q_inertial_from_body.norm(), 1.0, 1e-12);
    } else {
      ++refused;
      EXPECT_THAT(error, ::testing::MatchesRegex(Escaped(f) + ":[0-9]+: [^:]+: .+")) << error;
    }
  }
  std::printf("samples: %zu read, %zu refused with file, line and keyword\n", read, refused);
  EXPECT_EQ(read, must_read.size());
  EXPECT_GT(refused, 0u);
}

// read -> write -> read of every sample that is read: no number moves beyond the printed precision,
// in either encoding (the epochs come back in UTC whatever time system the sample used).
TEST(AdmSamples, ReadWriteReadChangesNoNumber) {
  SSIU_REQUIRE_SHARED(dir, "ccsds/samples");
  int n = 0;
  for (const std::string& f : SampleFiles(dir)) {
    AttitudeHistory h;
    try {
      h = ReadAdmFile(f);
    } catch (const InputError&) {
      continue;
    }
    SCOPED_TRACE(f);
    for (bool xml : {false, true}) {
      const AttitudeHistory again = ParseAdm(FormatAdm(h, h.message, xml), "again", h.epoch_utc);
      ExpectSameHistory(h, again);
    }
    ++n;
  }
  EXPECT_EQ(n, 15);
}

// A message another tool wrote in both encodings (orbit-formats: KVN 1.0, XML 2.0) reads the same.
TEST(AdmSamples, KvnAndXmlTwinsOfAnotherToolReadTheSame) {
  SSIU_REQUIRE_SHARED(kvn, "ccsds/samples/orbitformats_golden_aem.aem");
  SSIU_REQUIRE_SHARED(xml, "ccsds/samples/orbitformats_golden_aem.xml");
  ExpectSameHistory(ReadAdmFile(kvn), ReadAdmFile(xml));
}

// The blue-book style ACM example (SDO): the quaternion Q1 Q2 Q3 QC and the gyro bias in deg/s.
TEST(AdmSamples, AcmQuaternionAndGyroBiasAsPrinted) {
  SSIU_REQUIRE_SHARED(path, "ccsds/samples/orekit-acm_ACMExample02.txt");
  const AttitudeHistory h = ReadAdmFile(path);
  ASSERT_EQ(h.states.size(), 4u);
  EXPECT_EQ(h.epoch_utc.substr(0, 19), "2017-12-26T19:40:00");
  EXPECT_NEAR(h.states[2].t_s, 99.80183, 1e-9);
  const Quat q = Quat(0.4433, 0.1017, -0.1332, 0.8806).normalized();  // J2000 -> SC_BODY_1: as written
  EXPECT_THAT(h.states[2].q_inertial_from_body, QuaternionNear(q, 1e-6));
  ASSERT_TRUE(h.states[2].gyro_bias_rad_s.has_value());
  EXPECT_NEAR(h.states[2].gyro_bias_rad_s->y(), 8.769e-06 * kDegToRad, 1e-15);
  ASSERT_TRUE(h.determination.has_value());
  EXPECT_EQ(h.determination->method, "EKF");
  EXPECT_EQ(h.determination->sensors.size(), 4u);
}

// ADM 1.0 (504.0-B-1): QUATERNION_TYPE = FIRST puts QC first (Orekit's AEM example 4); ATTITUDE_DIR =
// B2A means the quaternion rotates REF_FRAME_B into REF_FRAME_A, so the same numbers give the inverse.
TEST(AdmSamples, Adm1QuaternionTypeAndDirection) {
  SSIU_REQUIRE_SHARED(path, "ccsds/samples/orekit-aem_AEMExample04.txt");
  const AttitudeHistory h = ReadAdmFile(path);
  ASSERT_FALSE(h.states.empty());
  EXPECT_THAT(h.states[0].q_inertial_from_body,
              QuaternionNear(Quat(0.488615, -0.402157, 0.581628, 0.511111).normalized(), 1e-6));
  std::ifstream f(path);
  std::ostringstream text;
  text << f.rdbuf();
  std::string b2a = text.str();
  b2a.replace(b2a.find("A2B"), 3, "B2A");
  const AttitudeHistory inv = ParseAdm(b2a, "b2a.aem");
  EXPECT_THAT(inv.states[0].q_inertial_from_body, QuaternionNear(h.states[0].q_inertial_from_body.conjugate(), 1e-6));
}

// Every malformed message of the other tools' own tests that reaches what ssiu reads is refused, naming
// the file, the line and the keyword (aemLowerCaseValue is Orekit's check that lower-case values are read).
TEST(AdmSamples, NegativeSamplesAreRefusedWithFileLineKeyword) {
  SSIU_REQUIRE_SHARED(dir, "ccsds/samples/negative");
  int n = 0;
  for (const std::string& f : SampleFiles(dir)) {
    if (f.find("aemLowerCaseValue") != std::string::npos) continue;
    SCOPED_TRACE(f);
    const std::string error = testing::ErrorOf([&] { ReadAdmFile(f); });
    EXPECT_THAT(error, ::testing::MatchesRegex(Escaped(f) + ":[0-9]+: [^:]+: .+"));
    ++n;
  }
  EXPECT_GT(n, 30);
}

// xmllint with the official NDM/XML 4.0.0 schemas (master: any NDM root) on what ssiu writes.
TEST(AdmSchemas, EveryXmlMessageWrittenValidates) {
  SSIU_REQUIRE_SHARED(xsd, "ccsds/xsd/ndmxml-4.0.0-master-4.0.xsd");
  std::string out;
  if (testing::Run("command -v xmllint", &out) != 0) GTEST_SKIP() << "xmllint not found (Debian package libxml2-utils)";
  const std::string dir = testing::TempDir("adm_schema");
  int n = 0;
  for (bool rates : {false, true})
    for (bool bias : {false, true})
      for (bool cov : {false, true})
        for (AdmMessage m : {AdmMessage::kAem, AdmMessage::kAcm}) {
          if (m == AdmMessage::kAem && (bias || cov)) continue;
          AttitudeHistory h = Slew(rates, bias, cov);
          if (m == AdmMessage::kAem) h.determination.reset();
          const std::string path = dir + "/msg" + std::to_string(n++) + ".xml";
          WriteAdmFile(path, h, m);
          EXPECT_EQ(testing::Run("xmllint --noout --nonet --schema '" + xsd + "' '" + path + "' 2>&1", &out), 0) << out;
        }
  EXPECT_EQ(n, 10);
}

}  // namespace
}  // namespace ssiu
