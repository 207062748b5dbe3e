// Real frames with published plate solutions (../shared/data/SOURCES.md): openstartracker img0, 2,
// 3 (astrometry.net), the other frames astrometry.net solved, and the tetra3 TIFFs. Skipped when ../shared is absent.
#include "testing/real_frames.h"

#include <cmath>
#include <cstdio>
#include <iterator>
#include <memory>
#include <string>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/image.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

double SepArcsec(double ra1_deg, double dec1_deg, double ra2_deg, double dec2_deg) {
  const Vec3 a = UnitFromRaDec(ra1_deg * kDegToRad, dec1_deg * kDegToRad);
  const Vec3 b = UnitFromRaDec(ra2_deg * kDegToRad, dec2_deg * kDegToRad);
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kRadToArcsec;
}

struct Published {
  const char* file;
  double ra_deg, dec_deg;
};

TEST(RealFrames, OpenStarTrackerWithinTenArcsecOfAstrometryNet) {
  SSIU_REQUIRE_SHARED(dark_path, "openstartracker/median_image.png");
  const Camera cam = testing::OpenStarTrackerCamera(206264.806 / 15.7768356032);  // calibration.txt PIXSCALE
  SolveOptions so;
  so.identify.fov_tolerance_pct = 1.0;
  const StarIdentifier id = MakeIdentifierForCamera("", cam, so.identify.fov_tolerance_pct);
  const Frame dark = ReadFrame(dark_path);
  const Published refs[] = {
      {"img0.png", 181.171161, 16.836005}, {"img2.png", 154.015478, 19.157137}, {"img3.png", 169.985553, 13.750871}};
  for (const auto& ref : refs) {
    SSIU_REQUIRE_SHARED(path, std::string("openstartracker/") + ref.file);
    const Frame fr = SubtractDark(ReadFrame(path), dark);
    const SolveResult r = SolveFrame(id, fr.image.view(), cam, so);
    ASSERT_EQ(r.status, SolveStatus::kSolved) << ref.file << ": " << r.message;
    const RaDecRoll a = RaDecRollFromQuat(r.attitude.q_inertial_from_sensor);
    const double err = SepArcsec(a.ra_rad * kRadToDeg, a.dec_rad * kRadToDeg, ref.ra_deg, ref.dec_deg);
    EXPECT_LT(err, 10.0) << ref.file;
    std::printf("%s: %zu stars, boresight %.2f arcsec from astrometry.net, f %.1f px\n", ref.file,
                r.identification.matches.size(), err, r.identification.focal_length_px);
  }
}

// Issue 14: the seven frames astrometry.net solved upstream (img0, 2, 3, 4, 6, 7, 9) with default
// options. The camera is the one those solutions measured: the mean of the three published
// PIXSCALEs of SOURCES.md (15.7376 arcsec/px); calibration.txt's 15.777 is 0.25% long, which puts
// corner stars ~1.7 px off and leaves img7 at a chance probability of 1.6e-5 (docs/results.md).
// References: img0, 2, 3 the published solutions; img4 and img6 the field centres that
// astrometry.net 0.93 (Debian, tycho2 index 07-19) found from our own detections
// (`solve-field --width 1392 --height 1040 --scale-units arcsecperpix --scale-low 15.5
// --scale-high 16 --odds-to-solve 1e6 xyN.fits`, docs/results.md); img7 and img9 have no
// independent solution here and must at least be self-consistent.
TEST(RealFrames, OpenStarTrackerSevenFramesSolveWithDefaultOptions) {
  SSIU_REQUIRE_SHARED(dark_path, "openstartracker/median_image.png");
  const Camera cam = testing::OpenStarTrackerCamera(206264.806 / ((15.70898 + 15.77684 + 15.72696) / 3));
  const SolveOptions so;  // defaults: fixed focal length, max-false-prob 1e-5, 50 ms
  const StarIdentifier id = MakeIdentifierForCamera("", cam, so.identify.fov_tolerance_pct);
  const Frame dark = ReadFrame(dark_path);
  struct Ref {
    const char* file;
    double ra_deg, dec_deg;  // NaN: no independent reference
    double limit_arcsec;
  };
  const double none = std::nan("");
  const Ref refs[] = {{"img0.png", 181.171161, 16.836005, 10},
                      {"img2.png", 154.015478, 19.157137, 10},
                      {"img3.png", 169.985553, 13.750871, 10},
                      {"img4.png", 179.818629, 15.737128, 15},
                      {"img6.png", 151.964708, 19.151409, 15},
                      {"img7.png", none, none, 0},
                      {"img9.png", none, none, 0}};
  for (const auto& ref : refs) {
    SSIU_REQUIRE_SHARED(path, std::string("openstartracker/") + ref.file);
    const SolveResult r = SolveFrame(id, SubtractDark(ReadFrame(path), dark).image.view(), cam, so);
    ASSERT_EQ(r.status, SolveStatus::kSolved) << ref.file << ": " << r.message;
    EXPECT_LT(r.identification.false_match_probability, so.identify.max_false_match_prob) << ref.file;
    EXPECT_GE(r.identification.matches.size(), 5u) << ref.file;
    // 1.6 px: the uncalibrated lens puts corner stars up to 1.2 px (18 arcsec) off a pinhole.
    for (const auto& m : r.identification.matches) EXPECT_LT(m.residual_rad * kRadToArcsec, 25.0) << ref.file;
    const RaDecRoll a = RaDecRollFromQuat(r.attitude.q_inertial_from_sensor);
    double err = -1;
    if (!std::isnan(ref.ra_deg)) {
      err = SepArcsec(a.ra_rad * kRadToDeg, a.dec_rad * kRadToDeg, ref.ra_deg, ref.dec_deg);
      EXPECT_LT(err, ref.limit_arcsec) << ref.file;
    }
    std::printf("%s: %zu stars, chance %.2g, ra %.5f dec %.5f, %.1f arcsec from the reference\n", ref.file,
                r.identification.matches.size(), r.identification.false_match_probability, a.ra_rad * kRadToDeg,
                a.dec_rad * kRadToDeg, err);
  }
}

// Issue 27: the focal length a user knows to ~0.3% (13074 px from calibration.txt's plate scale;
// the published solutions measured 13107), as a camera.json would give it: no tolerance flag, no
// dark. The stars refit it (IdentifyOptions::refine_focal_p) and every frame lands within 20 arcsec
// of the reference; img7 and img9, without an independent solution here, within 20 arcsec of the
// solve with the focal length searched (+-1%), which is within 10 arcsec of the references above.
TEST(RealFrames, OpenStarTrackerNominalFocalLengthIsRefinedByDefault) {
  Camera cam = testing::OpenStarTrackerCamera(13074);
  const SolveOptions so;
  SolveOptions searched;
  searched.identify.fov_tolerance_pct = 1.0;
  const StarIdentifier id = MakeIdentifierForCamera("", cam, searched.identify.fov_tolerance_pct);
  struct Ref {
    const char* file;
    double ra_deg, dec_deg;  // NaN: the searched solve is the reference
  };
  const double none = std::nan("");
  const Ref refs[] = {{"img0.png", 181.171161, 16.836005}, {"img2.png", 154.015478, 19.157137},
                      {"img3.png", 169.985553, 13.750871}, {"img4.png", 179.818629, 15.737128},
                      {"img6.png", 151.964708, 19.151409}, {"img7.png", none, none},
                      {"img9.png", none, none}};
  int refined = 0;
  for (const auto& ref : refs) {
    SSIU_REQUIRE_SHARED(path, std::string("openstartracker/") + ref.file);
    const Frame fr = ReadFrame(path);
    const SolveResult r = SolveFrame(id, fr.image.view(), cam, so);
    ASSERT_EQ(r.status, SolveStatus::kSolved) << ref.file << ": " << r.message;
    const RaDecRoll a = RaDecRollFromQuat(r.attitude.q_inertial_from_sensor);
    double ra = ref.ra_deg, dec = ref.dec_deg;
    if (std::isnan(ra)) {
      const SolveResult t = SolveFrame(id, fr.image.view(), cam, searched);
      ASSERT_EQ(t.status, SolveStatus::kSolved) << ref.file;
      const RaDecRoll b = RaDecRollFromQuat(t.attitude.q_inertial_from_sensor);
      ra = b.ra_rad * kRadToDeg, dec = b.dec_rad * kRadToDeg;
    }
    const double err = SepArcsec(a.ra_rad * kRadToDeg, a.dec_rad * kRadToDeg, ra, dec);
    EXPECT_LT(err, 20.0) << ref.file;
    refined += r.identification.focal_length_refined;
    if (r.identification.focal_length_refined) {
      // The three published plate scales (SOURCES.md) give 13074-13130 px.
      EXPECT_NEAR(r.identification.focal_length_px, 13107, 40) << ref.file;
      EXPECT_GT(r.identification.focal_length_sigma_px, 0) << ref.file;
    }
    std::printf("%s: %zu stars, f %.1f +- %.1f px (p %.2g), %.1f arcsec from the reference\n", ref.file,
                r.identification.matches.size(), r.identification.focal_length_px,
                r.identification.focal_length_sigma_px, r.identification.focal_length_p_value, err);
  }
  std::printf("focal length refined in %d of %zu frames\n", refined, std::size(refs));
  EXPECT_GE(refined, 6);
}

TEST(RealFrames, Tetra3AllEightSolvedPublishedOnesWithinTenArcsec) {
  SSIU_REQUIRE_SHARED(dir, "tetra3");
  Camera cam;
  cam.width = 1024, cam.height = 768;
  cam.focal_length_px = 512.0 / std::tan(5.7 * kDegToRad);  // about 11.4 deg across
  cam.cx_px = 511.5, cam.cy_px = 383.5;
  SolveOptions so;
  so.identify.fov_tolerance_pct = 3.0;
  const StarIdentifier id = MakeIdentifierForCamera("", cam, so.identify.fov_tolerance_pct);
  const char* names[] = {"Alt40_Azi-135", "Alt40_Azi-45", "Alt40_Azi135", "Alt40_Azi45",
                         "Alt60_Azi-135", "Alt60_Azi-45", "Alt60_Azi135", "Alt60_Azi45"};
  for (const char* n : names) {
    const std::string path = dir + "/2019-07-29T204726_" + n + "_Try1.tiff";
    const Frame fr = ReadFrame(path);
    const SolveResult r = SolveFrame(id, fr.image.view(), cam, so);
    ASSERT_EQ(r.status, SolveStatus::kSolved) << n << ": " << r.message;
    const RaDecRoll a = RaDecRollFromQuat(r.attitude.q_inertial_from_sensor);
    double err = -1;
    if (std::string(n) == "Alt40_Azi-45")
      err = SepArcsec(a.ra_rad * kRadToDeg, a.dec_rad * kRadToDeg, 172.3689, 57.6493);
    if (std::string(n) == "Alt60_Azi-45")
      err = SepArcsec(a.ra_rad * kRadToDeg, a.dec_rad * kRadToDeg, 212.2123, 64.2002);
    if (err >= 0) {
      EXPECT_LT(err, 10.0) << n;
    }
    std::printf("%s: %zu stars, ra %.4f dec %.4f roll %.3f, f %.1f px, vs published %.2f arcsec\n", n,
                r.identification.matches.size(), a.ra_rad * kRadToDeg, a.dec_rad * kRadToDeg, a.roll_rad * kRadToDeg,
                r.identification.focal_length_px, err);
  }
}

TEST(RealFrames, OpenStarTrackerHardFramesAreNeverWrong) {
  // img1, 5, 8 have no published solution: a solve must at least be self-consistent (chance
  // probability below the threshold and sub-10-arcsec residuals); no_match is acceptable.
  SSIU_REQUIRE_SHARED(dark_path, "openstartracker/median_image.png");
  const Camera cam = testing::OpenStarTrackerCamera(206264.806 / 15.7768356032);
  SolveOptions so;
  so.identify.fov_tolerance_pct = 1.0;
  const StarIdentifier id = MakeIdentifierForCamera("", cam, so.identify.fov_tolerance_pct);
  const Frame dark = ReadFrame(dark_path);
  for (const char* f : {"img1.png", "img5.png", "img8.png"}) {
    SSIU_REQUIRE_SHARED(path, std::string("openstartracker/") + f);
    const SolveResult r = SolveFrame(id, SubtractDark(ReadFrame(path), dark).image.view(), cam, so);
    std::printf("%s: %s (%s)\n", f, SolveStatusName(r.status), r.message.c_str());
    EXPECT_NE(r.status, SolveStatus::kTooFewStars) << f;
    if (r.status == SolveStatus::kSolved) {
      EXPECT_LT(r.identification.false_match_probability, 1e-5);
      for (const auto& m : r.identification.matches) EXPECT_LT(m.residual_rad * kRadToArcsec, 15.0) << f;
    }
  }
}

}  // namespace
}  // namespace ssiu
