// The OpenCV edge of this stage (core/opencv_edge.h): the overlay is drawn by overlay.cc in
// libssiu_opencv.so, loaded on first use.
#include "attitude/overlay.h"
#include "core/opencv_edge.h"

namespace ssiu {

void WriteSolveOverlay(const std::string& path, const ImageView& image, const Camera& camera, const StarIdentifier& id,
                       const SolveResult& result) {
  static const auto fn = OpenCvEdge<decltype(&WriteSolveOverlay)>("WriteSolveOverlay");
  fn(path, image, camera, id, result);
}

}  // namespace ssiu
