#include "core/heads.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

Json Head(const Json& q) {
  return {{"camera", {{"width", 512}, {"height", 384}, {"focal_length_px", 1755}}}, {"q_body_sensor", q}};
}

std::string Error(const Json& list, const std::string& field = "") {
  try {
    HeadsFromJson(list, "h.json", field);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// heads.json and a mission's "heads" field are read by one function: cameras and mounts as written
// (the mount normalised), and every error names the file, the list or the head, and the field.
TEST(Heads, ReadsCamerasAndMountsAndNamesEveryError) {
  const double s = std::sqrt(0.5);
  const std::vector<OpticalHead> hs =
      HeadsFromJson(Json::array({Head({1, 0, 0, 0}), Head({2 * s, 0, 2 * s, 0})}), "h.json");
  ASSERT_EQ(hs.size(), 2u);
  EXPECT_EQ(hs[1].camera.width, 512);
  EXPECT_EQ(hs[1].camera.height, 384);
  EXPECT_DOUBLE_EQ(hs[1].camera.focal_length_px, 1755);
  // 90 deg about y: the sensor's +Z is the body's +X.
  EXPECT_NEAR((hs[1].q_body_from_sensor * Vec3::UnitZ() - Vec3::UnitX()).norm(), 0, 1e-12);

  EXPECT_THAT(Error(Json::object()), HasSubstr("h.json: must be a list of 1 to 3 heads"));
  EXPECT_THAT(Error(Json::array()), HasSubstr("h.json: 0 heads given"));
  const Json h = Head({1, 0, 0, 0});
  EXPECT_THAT(Error(Json::array({h, h, h, h}), "heads"), HasSubstr("h.json: field 'heads': 4 heads given"));
  EXPECT_THAT(Error(Json::array({h, 3}), "heads"), HasSubstr("h.json: heads[1]: must be an object"));
  EXPECT_THAT(Error(Json::array({{{"camera", h["camera"]}}})), HasSubstr("h.json: [0]: missing field 'q_body_sensor'"));
  EXPECT_THAT(Error(Json::array({Head({0, 0, 0, 0})})), HasSubstr("q_body_sensor"));
  Json typo = h;
  typo["q_body_sensr"] = typo["q_body_sensor"];
  EXPECT_THAT(Error(Json::array({typo})), HasSubstr("unknown key 'q_body_sensr'"));
  Json no_focal = h;
  no_focal["camera"].erase("focal_length_px");
  EXPECT_THAT(Error(Json::array({h, no_focal}), "heads"),
              HasSubstr("h.json: heads[1].camera: missing field 'focal_length_px'"));
}

}  // namespace
}  // namespace ssiu
