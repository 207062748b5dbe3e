#include "plot/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "core/error.h"

namespace ssiu {
namespace {

bool Drawable(double v, bool log) { return std::isfinite(v) && (!log || v > 0); }

}  // namespace

void PlotOptions::Check() const {
  if (width_px < 200 || height_px < 150 || width_px > 8000 || height_px > 8000) {
    throw InputError("PlotOptions: size must be 200x150 .. 8000x8000 px");
  }
}

PlotFrame::PlotFrame(const std::vector<PlotSeries>& series, const PlotOptions& o) : log_x_(o.log_x), log_y_(o.log_y) {
  left = 95;
  right = o.width_px - 25;
  top = 45;
  bottom = o.height_px - 60;
  x_min = y_min = std::numeric_limits<double>::infinity();
  x_max = y_max = -std::numeric_limits<double>::infinity();
  for (const auto& s : series) {
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!Drawable(s.x[i], log_x_) || !Drawable(s.y[i], log_y_)) continue;
      x_min = std::min(x_min, s.x[i]);
      x_max = std::max(x_max, s.x[i]);
      y_min = std::min(y_min, s.y[i]);
      y_max = std::max(y_max, s.y[i]);
      if (i < s.y_lo.size() && Drawable(s.y_lo[i], log_y_)) y_min = std::min(y_min, s.y_lo[i]);
      if (i < s.y_hi.size() && Drawable(s.y_hi[i], log_y_)) y_max = std::max(y_max, s.y_hi[i]);
    }
  }
  valid_ = x_min <= x_max && y_min <= y_max;
  if (!valid_) {
    x_min = log_x_ ? 1 : 0;
    x_max = log_x_ ? 10 : 1;
    y_min = log_y_ ? 1 : 0;
    y_max = log_y_ ? 10 : 1;
    return;
  }
  // Pad: to whole decades on log axes, 5% on linear ones.
  auto pad = [](double& lo, double& hi, bool log) {
    if (log) {
      lo = std::pow(10.0, std::floor(std::log10(lo) + 1e-9));
      hi = std::pow(10.0, std::ceil(std::log10(hi) - 1e-9));
      if (hi <= lo) hi = lo * 10;
    } else {
      const double span = hi > lo ? hi - lo : std::max(1.0, std::abs(lo));
      lo -= 0.05 * span;
      hi += 0.05 * span;
    }
  };
  pad(x_min, x_max, log_x_);
  pad(y_min, y_max, log_y_);
}

double PlotFrame::PixelX(double x) const {
  const double f = log_x_ ? std::log(x / x_min) / std::log(x_max / x_min) : (x - x_min) / (x_max - x_min);
  return left + f * (right - left);
}

double PlotFrame::PixelY(double y) const {
  const double f = log_y_ ? std::log(y / y_min) / std::log(y_max / y_min) : (y - y_min) / (y_max - y_min);
  return bottom - f * (bottom - top);
}

}  // namespace ssiu
