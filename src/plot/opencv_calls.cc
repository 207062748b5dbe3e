// The OpenCV edge of this stage (core/opencv_edge.h): plots are drawn by plot_cv.cc in libssiu_opencv.so, loaded
// on first use.
#include "core/opencv_edge.h"
#include "plot/plot.h"

namespace ssiu {

void WritePlotPng(const std::string& path, const std::vector<PlotSeries>& series, const PlotOptions& options) {
  static const auto fn = OpenCvEdge<decltype(&WritePlotPng)>("WritePlotPng");
  fn(path, series, options);
}

}  // namespace ssiu
