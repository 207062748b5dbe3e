// The OpenCV edge of this stage (core/opencv_edge.h): residual quivers are drawn by discover_plot.cc in
// libssiu_opencv.so, loaded on first use.
#include "core/opencv_edge.h"
#include "discover/discover_frames.h"

namespace ssiu {

void WriteResidualQuiver(const std::string& dir, const FrameDiscovery& d, const Camera& camera) {
  static const auto fn = OpenCvEdge<decltype(&WriteResidualQuiver)>("WriteResidualQuiver");
  fn(dir, d, camera);
}

}  // namespace ssiu
