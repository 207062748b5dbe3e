// A small PNG plotting module (OpenCV stays inside plot.cc): axes with ticks and grid, linear or
// log-log scales, lines, markers, error bars, a title, axis labels and a legend. Enough for
// diagnostic figures such as Allan-deviation curves; not a general plotting library.
#pragma once

#include <string>
#include <vector>

namespace ssiu {

struct PlotColor {
  unsigned char r = 0, g = 0, b = 0;
};

struct PlotSeries {
  std::string label;  // legend entry; empty = not in the legend
  std::vector<double> x, y;
  std::vector<double> y_lo;  // optional error bars: both empty or both the size of y
  std::vector<double> y_hi;
  PlotColor color;
  bool line = true;      // polyline through the points (broken at points that cannot be drawn)
  bool markers = false;  // a small circle at each point
  bool dashed = false;
  int thickness_px = 2;
};

struct PlotOptions {
  int width_px = 960;
  int height_px = 680;
  bool log_x = false;
  bool log_y = false;
  std::string title, x_label, y_label;
  bool legend_bottom_left = false;  // default top right; bottom left suits falling curves (ADEV)
  void Check() const;               // InputError on a bad value
};

// Maps data to pixels for a given set of series and options (exposed so tests can find a point).
class PlotFrame {
 public:
  PlotFrame(const std::vector<PlotSeries>& series, const PlotOptions& options);
  bool Valid() const { return valid_; }  // false when no point can be drawn
  double PixelX(double x) const;
  double PixelY(double y) const;
  double x_min, x_max, y_min, y_max;  // axis limits (data units)
  int left, right, top, bottom;       // plot area in pixels

 private:
  bool log_x_, log_y_, valid_ = false;
};

// Writes the plot to a PNG file; InputError naming the file when it cannot be written.
void WritePlotPng(const std::string& path, const std::vector<PlotSeries>& series, const PlotOptions& options);

}  // namespace ssiu
