#include "testing/real_frames.h"

#include "testing/testing.h"

namespace ssiu::testing {

Camera OpenStarTrackerCamera(double focal_length_px) {
  Camera cam;
  cam.width = 1392, cam.height = 1040;
  cam.focal_length_px = focal_length_px;
  cam.cx_px = 695.5, cam.cy_px = 519.5;
  return cam;
}

std::vector<ImageView> RealFrames::Views() const {
  std::vector<ImageView> views;
  for (const auto& f : frames) views.push_back(f.image.view());
  return views;
}

RealFrames OpenStarTrackerFrames() {
  const std::string dark_path = SharedData("openstartracker/median_image.png");
  if (dark_path.empty()) return {};
  const Frame dark = ReadFrame(dark_path);
  RealFrames out;
  for (int i = 0; i < 10; ++i) {
    const std::string path = SharedData("openstartracker/img" + std::to_string(i) + ".png");
    if (path.empty()) return {};
    out.frames.push_back(SubtractDark(ReadFrame(path), dark));
    out.names.push_back(path);
  }
  return out;
}

}  // namespace ssiu::testing
