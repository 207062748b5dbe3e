// The OpenCV edge of this stage (core/opencv_edge.h): mask_cv.cc, reference_cv.cc (with libapriltag)
// and virtual_stand_cv.cc are in libssiu_opencv.so, loaded on first use.
#include "core/opencv_edge.h"
#include "groundtest/mask.h"
#include "groundtest/reference.h"
#include "groundtest/virtual_stand.h"

namespace ssiu {

void WriteMaskPng(const Mask& m, const std::string& path, double dpi) {
  static const auto fn = OpenCvEdge<decltype(&WriteMaskPng)>("WriteMaskPng");
  fn(m, path, dpi);
}

std::vector<FiducialDetection> DetectFiducials(const uint8_t* pixels, int width, int height, const std::string& family,
                                               const FiducialOptions& o) {
  static const auto fn = OpenCvEdge<decltype(&DetectFiducials)>("DetectFiducials");
  return fn(pixels, width, height, family, o);
}

PlatePoseEstimate EstimatePlatePose(const Mask& m, const AuxCamera& aux, const uint8_t* pixels, int width, int height,
                                    const std::string& photo_name, const FiducialOptions& o) {
  static const auto fn = OpenCvEdge<decltype(&EstimatePlatePose)>("EstimatePlatePose");
  return fn(m, aux, pixels, width, height, photo_name, o);
}

Image16 RenderTrackerView(const Mask& m, const PlatePose& pose, const Quat& q_c_from_s, const TrackerViewOptions& o,
                          uint64_t seed, std::vector<ViewStar>* stars_in_view) {
  static const auto fn = OpenCvEdge<decltype(&RenderTrackerView)>("RenderTrackerView");
  return fn(m, pose, q_c_from_s, o, seed, stars_in_view);
}

std::vector<float> RenderAuxScene(const Mask& m, const PlatePose& pose, const AuxCamera& aux, const PhotoOptions& o,
                                  uint64_t seed) {
  static const auto fn = OpenCvEdge<decltype(&RenderAuxScene)>("RenderAuxScene");
  return fn(m, pose, aux, o, seed);
}

}  // namespace ssiu
