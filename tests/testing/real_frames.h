// The openstartracker frames of ../shared/data (SOURCES.md): the camera and the ten frames img0..img9,
// each minus the median dark frame, as several real-data tests load them.
#pragma once

#include <string>
#include <vector>

#include "core/camera.h"
#include "core/image.h"

namespace ssiu::testing {

// The openstartracker camera (1392 x 1040 px, principal point at the centre, no distortion) with
// the focal length a test assumes.
Camera OpenStarTrackerCamera(double focal_length_px);

struct RealFrames {
  std::vector<Frame> frames;       // dark-subtracted
  std::vector<std::string> names;  // their paths
  std::vector<ImageView> Views() const;
};

// img0..img9.png minus median_image.png; empty when any of them is absent (the test then skips:
// `if (f.frames.empty()) GTEST_SKIP() << ...`).
RealFrames OpenStarTrackerFrames();

}  // namespace ssiu::testing
