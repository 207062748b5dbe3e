// Defect maps hold only the map's levels: a star frame given as a map is refused (issue 16).
#include <random>

#include "core/error.h"
#include "core/image.h"
#include "detect/detect.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(DefectMap, SavedMapsLoadBackAndFramesAreRefused) {
  const std::string d = testing::TempDir("defect_map_levels");
  DefectMap m;
  m.width = 64, m.height = 48;
  m.mask.assign(64 * 48, 0);
  m.mask[5] = 1, m.mask[700] = 2, m.mask[1000] = 3;
  SaveDefectMap(d + "/map.png", m);
  const DefectMap back = LoadDefectMap(d + "/map.png");
  EXPECT_EQ(back.mask, m.mask);
  // A star frame: background with noise and a star, all levels in between.
  Image16 frame(64, 48, 0);
  std::mt19937 rng(3);
  for (auto& v : frame.pixels) v = static_cast<uint16_t>(200 + rng() % 20);
  frame.at(30, 20) = 5000;
  WritePng16(d + "/frame.png", frame);
  try {
    LoadDefectMap(d + "/frame.png");
    ADD_FAILURE() << "a star frame was accepted as a defect map";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("frame.png: not a defect map: pixel (0, 0)"));
  }
}

}  // namespace
}  // namespace ssiu
