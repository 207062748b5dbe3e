#include "core/camera.h"

#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(Camera, PinholeProjectionFollowsTheConvention) {
  Camera c;
  c.focal_length_px = 2300;
  c.cx_px = 511.5;
  c.cy_px = 500.0;
  const auto p = c.Project(Vec3(0.01, -0.02, 1.0));
  ASSERT_TRUE(p.has_value());
  EXPECT_NEAR(p->x(), 511.5 + 23.0, 1e-9);
  EXPECT_NEAR(p->y(), 500.0 - 46.0, 1e-9);
  EXPECT_FALSE(c.Project(Vec3(0, 0, -1)).has_value());
}

TEST(Camera, UnprojectInvertsProjectWithDistortion) {
  Camera c;
  c.distortion = {-0.3, 0.1, 0.0, 1e-3, -2e-3};
  for (double x : {0.0, 100.0, 900.0}) {
    for (double y : {5.0, 512.0, 1010.0}) {
      const Vec3 d = c.Unproject(Vec2(x, y));
      const auto p = c.Project(d);
      ASSERT_TRUE(p.has_value());
      EXPECT_NEAR(p->x(), x, 1e-6);
      EXPECT_NEAR(p->y(), y, 1e-6);
    }
  }
}

TEST(Camera, NonSquarePixelsProjectWithFxAndFy) {
  Camera c;
  c.focal_length_px = 2300;
  c.focal_length_y_px = 1150;  // pixels twice as tall as wide
  c.cx_px = 511.5;
  c.cy_px = 500.0;
  const auto p = c.Project(Vec3(0.01, -0.02, 1.0));
  ASSERT_TRUE(p.has_value());
  EXPECT_NEAR(p->x(), 511.5 + 23.0, 1e-9);
  EXPECT_NEAR(p->y(), 500.0 - 23.0, 1e-9);
  EXPECT_NEAR(c.FovYRad(), 2 * std::atan(512.0 / 1150), 1e-12);
  EXPECT_NEAR(c.FocalMeanPx(), std::sqrt(2300.0 * 1150), 1e-9);
  // Round trip through the distortion with fx != fy.
  c.distortion = {-0.2, 0.05, 0.0, 5e-4, -1e-3};
  for (double x : {3.0, 400.0, 1000.0}) {
    for (double y : {10.0, 700.0, 1015.0}) {
      const auto q = c.Project(c.Unproject(Vec2(x, y)));
      ASSERT_TRUE(q.has_value());
      EXPECT_NEAR(q->x(), x, 1e-6);
      EXPECT_NEAR(q->y(), y, 1e-6);
    }
  }
  // A common scale keeps the aspect.
  Camera s = c;
  s.ScaleFocal(1.01);
  EXPECT_NEAR(s.FocalYPx() / s.focal_length_px, 0.5, 1e-15);
}

TEST(Camera, FocalLengthYReadAndWrittenExactly) {
  const Json j = {
      {"width", 752}, {"height", 290}, {"focal_length_px", 2325.5813953488373}, {"focal_length_y_px", 1163.123456789}};
  const Camera c = CameraFromJson(j, "cam.json");
  EXPECT_EQ(c.focal_length_y_px, 1163.123456789);
  const Camera back = CameraFromJson(CameraToJson(c), "again");
  EXPECT_EQ(back.focal_length_px, c.focal_length_px);
  EXPECT_EQ(back.focal_length_y_px, c.focal_length_y_px);
  // Square pixels: no key written, fy reads as fx.
  const Camera sq = CameraFromJson({{"width", 100}, {"height", 100}, {"focal_length_px", 300}}, "sq.json");
  EXPECT_FALSE(CameraToJson(sq).contains("focal_length_y_px"));
  EXPECT_EQ(sq.FocalYPx(), 300);
  EXPECT_THROW(
      CameraFromJson({{"width", 100}, {"height", 100}, {"focal_length_px", 300}, {"focal_length_y_px", -1}}, "c.json"),
      InputError);
}

TEST(Camera, FocalLengthFromMillimetres) {
  const Json j = {{"width", 1392}, {"height", 1040}, {"focal_length_mm", 50.0}, {"pixel_pitch_um", 6.45}};
  const Camera c = CameraFromJson(j, "cam.json");
  EXPECT_NEAR(c.focal_length_px, 50.0 * 1000 / 6.45, 1e-9);
  EXPECT_NEAR(c.cx_px, 695.5, 1e-12);
  EXPECT_NEAR(c.cy_px, 519.5, 1e-12);
}

TEST(Camera, BadFieldsNameTheFileAndField) {
  auto message = [](const Json& j) {
    try {
      CameraFromJson(j, "cam.json");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_THAT(message({{"height", 10}, {"focal_length_px", 100}}),
              ::testing::HasSubstr("cam.json: missing field 'width'"));
  EXPECT_THAT(message({{"width", 100}, {"height", 100}}), ::testing::HasSubstr("focal_length_px"));
  EXPECT_THAT(message({{"width", -5}, {"height", 100}, {"focal_length_px", 100}}), ::testing::HasSubstr("width"));
  EXPECT_THAT(message({{"width", 100}, {"height", 100}, {"focal_length_px", -3}}),
              ::testing::HasSubstr("focal_length_px"));
  EXPECT_THAT(message({{"width", 100}, {"height", 100}, {"focal_length_px", "abc"}}),
              ::testing::HasSubstr("focal_length_px"));
  EXPECT_THAT(message({{"width", 100}, {"height", 100}, {"focal_length_px", 300}, {"principal_point", {500, 2}}}),
              ::testing::HasSubstr("principal_point"));
  EXPECT_THAT(message(Json::array()), ::testing::HasSubstr("object"));
}

// discover frames' fitted_camera carries the model's PSF, vignetting and hot pixels: every reader accepts
// them back (checked), and they survive the round trip; a bad one names the field.
TEST(Camera, ExtrasOfTheModelReadCheckedAndWrittenBack) {
  const Json j = {
      {"width", 100},        {"height", 80},           {"focal_length_px", 300}, {"vignetting", 0.3},
      {"psf_sigma_px", 0.7}, {"psf_ellipticity", 0.1}, {"psf_angle_deg", 80},    {"hot_pixels", {{3, 4}, {99, 79}}}};
  const Camera c = CameraFromJson(j, "cam.json");
  const CameraExtras e = CameraExtrasFromJson(j, c, "cam.json");
  EXPECT_EQ(e.vignetting, 0.3);
  EXPECT_EQ(e.psf_sigma_px, 0.7);
  ASSERT_EQ(e.hot_pixels.size(), 2u);
  EXPECT_EQ(e.hot_pixels[1][0], 99);
  EXPECT_EQ(e.hot_pixels[1][1], 79);
  Json back = CameraToJson(c);
  AddCameraExtras(e, &back);
  const CameraExtras e2 = CameraExtrasFromJson(back, CameraFromJson(back, "back"), "back");
  EXPECT_EQ(e2.vignetting, e.vignetting);
  EXPECT_EQ(e2.psf_ellipticity, e.psf_ellipticity);
  EXPECT_EQ(e2.psf_angle_deg, e.psf_angle_deg);
  EXPECT_EQ(e2.hot_pixels, e.hot_pixels);
  // Nothing set, nothing written.
  Json plain = CameraToJson(c);
  AddCameraExtras(CameraExtras{}, &plain);
  EXPECT_EQ(plain, CameraToJson(c));
  auto message = [&](const char* key, const Json& v) {
    Json bad = j;
    bad[key] = v;
    try {
      CameraFromJson(bad, "cam.json");
    } catch (const InputError& err) {
      return std::string(err.what());
    }
    return std::string("no error");
  };
  EXPECT_THAT(message("vignetting", 1.2), ::testing::HasSubstr("cam.json: field 'vignetting'"));
  EXPECT_THAT(message("hot_pixels", {{100, 4}}), ::testing::HasSubstr("'hot_pixels[0]' lies outside the 100x80"));
  EXPECT_THAT(message("hot_pixels", {{3, 4}, {5}}), ::testing::HasSubstr("'hot_pixels[1]' must be [x, y]"));
  EXPECT_THAT(message("hot_pixels", {{3.5, 4}}), ::testing::HasSubstr("hot_pixels[0]"));
  EXPECT_THAT(message("hot_pixels", 7), ::testing::HasSubstr("'hot_pixels' must be a list"));
  EXPECT_THAT(message("psf_ellipticity", 1.5), ::testing::HasSubstr("psf_ellipticity"));
}

TEST(Camera, LoadCameraReportsUnreadableFiles) {
  const std::string dir = testing::TempDir("cam");
  EXPECT_THROW(LoadCamera(dir + "/missing.json"), InputError);
  // A directory opens as a stream and used to fail inside the parser with an I/O exception (exit 2).
  try {
    LoadCamera(dir);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("is a directory"));
  }
  // Smaller than the detector's 16x16 minimum.
  EXPECT_THROW(CameraFromJson({{"width", 8}, {"height", 8}, {"focal_length_px", 100}}, "cam.json"), InputError);
  std::ofstream(dir + "/bad.json") << "{ not json";
  try {
    LoadCamera(dir + "/bad.json");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("bad.json"));
  }
}

}  // namespace
}  // namespace ssiu
