// The OpenCV edge of this stage (core/opencv_edge.h): FOG figures are drawn by fog_plot.cc in libssiu_opencv.so, loaded
// on first use.
#include "calibration/fog_plot.h"
#include "core/opencv_edge.h"

namespace ssiu {

void WriteFogPlotPng(const std::string& path, const FogPlot& plot) {
  static const auto fn = OpenCvEdge<decltype(&WriteFogPlotPng)>("WriteFogPlotPng");
  fn(path, plot);
}

}  // namespace ssiu
