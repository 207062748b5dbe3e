#include "calibration/fog_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/image_cv.h"

namespace ssiu {
namespace {

std::string Fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.4g", v);
  return buf;
}

// "Nice" tick step (1, 2, 5 x 10^k) giving about `target` ticks over `range`.
double TickStep(double range, int target) {
  const double raw = range / target;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= raw) return m * p;
  }
  return 10 * p;
}

}  // namespace

void WriteFogPlotPng(const std::string& path, const FogPlot& plot) {
  static const cv::Scalar kColors[] = {{180, 80, 20},  {30, 30, 200}, {40, 150, 40}, {150, 40, 150},
                                       {20, 140, 200}, {90, 90, 90},  {0, 100, 180}, {120, 160, 0}};
  cv::Mat img(plot.height_px, plot.width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  const int left = 90, right = 20, top = 40, bottom = 60;
  const int w = plot.width_px - left - right, h = plot.height_px - top - bottom;
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const auto& s : plot.series) {
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      x0 = std::min(x0, s.x[i]);
      x1 = std::max(x1, s.x[i]);
      y0 = std::min(y0, s.y[i]);
      y1 = std::max(y1, s.y[i]);
    }
  }
  if (!(x1 > x0)) {
    x0 = (x0 < 1e299 ? x0 : 0) - 1;
    x1 = x0 + 2;
  }
  if (!(y1 > y0)) {
    y0 = (y0 < 1e299 ? y0 : 0) - 1;
    y1 = y0 + 2;
  }
  const double pad = 0.05 * (y1 - y0);
  y0 -= pad;
  y1 += pad;
  auto px = [&](double x, double y) {
    return cv::Point(left + static_cast<int>(std::lround((x - x0) / (x1 - x0) * w)),
                     top + static_cast<int>(std::lround((y1 - y) / (y1 - y0) * h)));
  };
  const auto font = cv::FONT_HERSHEY_SIMPLEX;
  const cv::Scalar grid(225, 225, 225), ink(0, 0, 0);
  for (int pass = 0; pass < 2; ++pass) {
    const double lo = pass ? y0 : x0, hi = pass ? y1 : x1, step = TickStep(hi - lo, 8);
    for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step) {
      const double vv = std::abs(v) < 1e-9 * step ? 0.0 : v;
      if (pass == 0) {
        cv::line(img, px(vv, y0), px(vv, y1), grid, 1);
        cv::putText(img, Fmt(vv), px(vv, y0) + cv::Point(-15, 20), font, 0.45, ink, 1, cv::LINE_AA);
      } else {
        cv::line(img, px(x0, vv), px(x1, vv), grid, 1);
        cv::putText(img, Fmt(vv), px(x0, vv) + cv::Point(-80, 5), font, 0.45, ink, 1, cv::LINE_AA);
      }
    }
  }
  if (y0 < 0 && y1 > 0) cv::line(img, px(x0, 0), px(x1, 0), cv::Scalar(150, 150, 150), 1);
  cv::rectangle(img, cv::Point(left, top), cv::Point(left + w, top + h), ink, 1);
  for (size_t k = 0; k < plot.series.size(); ++k) {
    const auto& s = plot.series[k];
    const cv::Scalar col = kColors[k % 8];
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      if (s.markers) {
        cv::circle(img, px(s.x[i], s.y[i]), 3, col, cv::FILLED, cv::LINE_AA);
      } else if (i > 0 && std::isfinite(s.x[i - 1]) && std::isfinite(s.y[i - 1]) && s.x[i] >= s.x[i - 1]) {
        cv::line(img, px(s.x[i - 1], s.y[i - 1]), px(s.x[i], s.y[i]), col, 1, cv::LINE_AA);
      }
    }
    const cv::Point lp(left + 10, top + 18 + 18 * static_cast<int>(k));
    cv::line(img, lp, lp + cv::Point(25, 0), col, 2);
    cv::putText(img, s.label, lp + cv::Point(32, 5), font, 0.45, col, 1, cv::LINE_AA);
  }
  cv::putText(img, plot.title, cv::Point(left, 25), font, 0.6, ink, 1, cv::LINE_AA);
  cv::putText(img, plot.x_label, cv::Point(left + w / 2 - 40, plot.height_px - 15), font, 0.5, ink, 1, cv::LINE_AA);
  cv::putText(img, plot.y_label, cv::Point(5, top - 10), font, 0.5, ink, 1, cv::LINE_AA);
  WritePng(path, img);
}

}  // namespace ssiu
