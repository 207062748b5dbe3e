// WritePlotPng: the drawing half of plot.h, in the OpenCV edge module (core/opencv_edge.h).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/error.h"
#include "core/image_cv.h"
#include "plot/plot.h"

namespace ssiu {
namespace {

bool Drawable(double v, bool log) { return std::isfinite(v) && (!log || v > 0); }

cv::Scalar Bgr(PlotColor c) { return cv::Scalar(c.b, c.g, c.r); }

std::string TickLabel(double v, bool log) {
  char buf[32];
  if (log) {
    const int e = static_cast<int>(std::lround(std::log10(v)));
    if (e >= -2 && e <= 3)
      std::snprintf(buf, sizeof buf, "%g", std::pow(10.0, e));
    else
      std::snprintf(buf, sizeof buf, "1e%d", e);
  } else {
    std::snprintf(buf, sizeof buf, "%g", v);
  }
  return buf;
}

// Ticks: every decade on a log axis, 1-2-5 steps on a linear one.
std::vector<double> Ticks(double lo, double hi, bool log) {
  std::vector<double> t;
  if (log) {
    for (int e = static_cast<int>(std::ceil(std::log10(lo) - 1e-9)); e <= std::floor(std::log10(hi) + 1e-9); ++e) {
      t.push_back(std::pow(10.0, e));
    }
    return t;
  }
  const double raw = (hi - lo) / 6, mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double step = raw / mag < 2 ? 2 * mag : raw / mag < 5 ? 5 * mag : 10 * mag;
  for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step) {
    t.push_back(std::abs(v) < 1e-12 * step ? 0 : v);
  }
  return t;
}

// Dashes of 8 px on, 8 px off; `phase` carries the pattern across the segments of one polyline.
void DashedLine(cv::Mat& img, cv::Point2d a, cv::Point2d b, cv::Scalar color, int thickness, double* phase) {
  const double len = std::hypot(b.x - a.x, b.y - a.y), dash = 8;
  if (len <= 0) return;
  double s = 0;
  while (s < len) {
    const double in_period = std::fmod(*phase + s, 2 * dash);
    const double step = std::min(len - s, in_period < dash ? dash - in_period : 2 * dash - in_period);
    if (in_period < dash)
      cv::line(img, a + (b - a) * (s / len), a + (b - a) * ((s + step) / len), color, thickness, cv::LINE_AA);
    s += step;
  }
  *phase = std::fmod(*phase + len, 2 * dash);
}

}  // namespace

void WritePlotPng(const std::string& path, const std::vector<PlotSeries>& series, const PlotOptions& o) {
  o.Check();
  for (const auto& s : series) {
    if (s.x.size() != s.y.size()) throw InputError("PlotSeries '" + s.label + "': x and y differ in size");
    if ((!s.y_lo.empty() || !s.y_hi.empty()) && (s.y_lo.size() != s.y.size() || s.y_hi.size() != s.y.size())) {
      throw InputError("PlotSeries '" + s.label + "': error bars must match y in size");
    }
  }
  const PlotFrame f(series, o);
  cv::Mat img(o.height_px, o.width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  const cv::Scalar black(0, 0, 0), grid(225, 225, 225);
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  // Grid and ticks.
  for (double t : Ticks(f.x_min, f.x_max, o.log_x)) {
    const int px = static_cast<int>(std::lround(f.PixelX(t)));
    cv::line(img, {px, f.top}, {px, f.bottom}, grid, 1);
    cv::line(img, {px, f.bottom}, {px, f.bottom + 5}, black, 1);
    const std::string s = TickLabel(t, o.log_x);
    int base = 0;
    const cv::Size sz = cv::getTextSize(s, font, 0.45, 1, &base);
    cv::putText(img, s, {px - sz.width / 2, f.bottom + 20}, font, 0.45, black, 1, cv::LINE_AA);
  }
  for (double t : Ticks(f.y_min, f.y_max, o.log_y)) {
    const int py = static_cast<int>(std::lround(f.PixelY(t)));
    cv::line(img, {f.left, py}, {f.right, py}, grid, 1);
    cv::line(img, {f.left - 5, py}, {f.left, py}, black, 1);
    const std::string s = TickLabel(t, o.log_y);
    int base = 0;
    const cv::Size sz = cv::getTextSize(s, font, 0.45, 1, &base);
    cv::putText(img, s, {f.left - 8 - sz.width, py + sz.height / 2}, font, 0.45, black, 1, cv::LINE_AA);
  }
  // Log-axis minor ticks (2..9 of each decade).
  if (o.log_x) {
    for (double d = f.x_min; d < f.x_max; d *= 10) {
      for (int k = 2; k <= 9; ++k) {
        const int px = static_cast<int>(std::lround(f.PixelX(d * k)));
        cv::line(img, {px, f.bottom}, {px, f.bottom + 3}, black, 1);
      }
    }
  }
  if (o.log_y) {
    for (double d = f.y_min; d < f.y_max; d *= 10) {
      for (int k = 2; k <= 9; ++k) {
        const int py = static_cast<int>(std::lround(f.PixelY(d * k)));
        cv::line(img, {f.left - 3, py}, {f.left, py}, black, 1);
      }
    }
  }
  cv::rectangle(img, {f.left, f.top}, {f.right, f.bottom}, black, 1);
  // Drawing into a region of interest clips to the plot area; points are shifted to its origin.
  cv::Mat area = img(cv::Rect(f.left, f.top, f.right - f.left + 1, f.bottom - f.top + 1));
  const cv::Point2d origin(f.left, f.top);
  for (const auto& s : series) {
    const cv::Scalar c = Bgr(s.color);
    auto ok = [&](size_t i) { return Drawable(s.x[i], o.log_x) && Drawable(s.y[i], o.log_y); };
    auto pt = [&](size_t i) { return cv::Point2d(f.PixelX(s.x[i]), f.PixelY(s.y[i])) - origin; };
    if (!s.y_lo.empty()) {
      for (size_t i = 0; i < s.y.size(); ++i) {
        if (!Drawable(s.x[i], o.log_x)) continue;
        const double lo = Drawable(s.y_lo[i], o.log_y) ? s.y_lo[i] : f.y_min;
        const double hi = Drawable(s.y_hi[i], o.log_y) ? s.y_hi[i] : f.y_max;
        const double px = f.PixelX(s.x[i]) - origin.x, ylo = f.PixelY(lo) - origin.y, yhi = f.PixelY(hi) - origin.y;
        cv::line(area, cv::Point2d(px, ylo), cv::Point2d(px, yhi), c, 1, cv::LINE_AA);
        cv::line(area, cv::Point2d(px - 3, ylo), cv::Point2d(px + 3, ylo), c, 1, cv::LINE_AA);
        cv::line(area, cv::Point2d(px - 3, yhi), cv::Point2d(px + 3, yhi), c, 1, cv::LINE_AA);
      }
    }
    if (s.line) {
      double phase = 0;
      for (size_t i = 1; i < s.x.size(); ++i) {
        if (!ok(i - 1) || !ok(i)) continue;
        if (s.dashed)
          DashedLine(area, pt(i - 1), pt(i), c, s.thickness_px, &phase);
        else
          cv::line(area, pt(i - 1), pt(i), c, s.thickness_px, cv::LINE_AA);
      }
    }
    if (s.markers) {
      for (size_t i = 0; i < s.x.size(); ++i) {
        if (ok(i)) cv::circle(area, pt(i), 3, c, cv::FILLED, cv::LINE_AA);
      }
    }
  }
  // Title and axis labels.
  cv::putText(img, o.title, {f.left, 28}, font, 0.6, black, 1, cv::LINE_AA);
  {
    int base = 0;
    const cv::Size sz = cv::getTextSize(o.x_label, font, 0.5, 1, &base);
    cv::putText(img, o.x_label, {(f.left + f.right - sz.width) / 2, o.height_px - 15}, font, 0.5, black, 1,
                cv::LINE_AA);
  }
  // The y label reads along the axis: drawn horizontally, then rotated by 90 degrees.
  if (!o.y_label.empty()) {
    int base = 0;
    const cv::Size sz = cv::getTextSize(o.y_label, font, 0.5, 1, &base);
    cv::Mat label(sz.height + base + 4, sz.width + 4, CV_8UC3, cv::Scalar(255, 255, 255));
    cv::putText(label, o.y_label, {2, sz.height + 2}, font, 0.5, black, 1, cv::LINE_AA);
    cv::Mat rotated;
    cv::rotate(label, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int y0 = std::max(0, (f.top + f.bottom - rotated.rows) / 2);
    if (rotated.rows + y0 <= img.rows && rotated.cols + 4 <= img.cols) {
      rotated.copyTo(img(cv::Rect(4, y0, rotated.cols, rotated.rows)));
    }
  }
  // Legend inside the plot area, top right or bottom left.
  int entries = 0, widest = 0;
  for (const auto& s : series) {
    if (s.label.empty()) continue;
    int base = 0;
    widest = std::max(widest, cv::getTextSize(s.label, font, 0.45, 1, &base).width);
    ++entries;
  }
  int row = 0;
  for (const auto& s : series) {
    if (s.label.empty()) continue;
    int base = 0;
    const cv::Size sz = cv::getTextSize(s.label, font, 0.45, 1, &base);
    const int y = o.legend_bottom_left ? f.bottom - 10 - 18 * (entries - 1 - row++) : f.top + 18 + 18 * row++;
    const int x = o.legend_bottom_left ? f.left + 45 : f.right - sz.width - 45;
    const int x_end = o.legend_bottom_left ? f.left + 45 + widest + 6 : f.right - 4;
    cv::rectangle(img, {x - 34, y - 13}, {x_end, y + 5}, cv::Scalar(255, 255, 255), cv::FILLED);
    cv::line(img, {x - 30, y - 4}, {x - 6, y - 4}, Bgr(s.color), 2, cv::LINE_AA);
    cv::putText(img, s.label, {x, y}, font, 0.45, black, 1, cv::LINE_AA);
  }
  WritePng(path, img);
}

}  // namespace ssiu
