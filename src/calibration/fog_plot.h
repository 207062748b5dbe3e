// Minimal PNG line plots for the FOG bench calibration figures (OpenCV drawing behind a small
// type, so callers do not see cv::Mat).
#pragma once

#include <string>
#include <vector>

namespace ssiu {

struct FogPlotSeries {
  std::string label;
  std::vector<double> x, y;
  bool markers = false;  // draw points instead of a line
};

struct FogPlot {
  std::string title, x_label, y_label;
  std::vector<FogPlotSeries> series;
  int width_px = 1000, height_px = 560;
};

// Writes the plot as a PNG; InputError when the file cannot be written.
void WriteFogPlotPng(const std::string& path, const FogPlot& plot);

}  // namespace ssiu
