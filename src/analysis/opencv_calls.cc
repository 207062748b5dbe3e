// The OpenCV edge of this stage (core/opencv_edge.h): plots are drawn by plot_cv.cc, fog_plot.cc and
// discover_plot.cc in libssiu_opencv.so, loaded on first use.
#include "analysis/discover_frames.h"
#include "analysis/fog_plot.h"
#include "analysis/plot.h"
#include "core/opencv_edge.h"

namespace ssiu {

void WritePlotPng(const std::string& path, const std::vector<PlotSeries>& series, const PlotOptions& options) {
  static const auto fn = OpenCvEdge<decltype(&WritePlotPng)>("WritePlotPng");
  fn(path, series, options);
}

void WriteFogPlotPng(const std::string& path, const FogPlot& plot) {
  static const auto fn = OpenCvEdge<decltype(&WriteFogPlotPng)>("WriteFogPlotPng");
  fn(path, plot);
}

void WriteResidualQuiver(const std::string& dir, const FrameDiscovery& d, const Camera& camera) {
  static const auto fn = OpenCvEdge<decltype(&WriteResidualQuiver)>("WriteResidualQuiver");
  fn(dir, d, camera);
}

}  // namespace ssiu
