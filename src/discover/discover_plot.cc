// Residual quiver plots of `ssiu discover frames --plot DIR` (OpenCV stays in this file).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/image_cv.h"
#include "discover/discover_frames.h"

namespace ssiu {

void WriteResidualQuiver(const std::string& dir, const FrameDiscovery& d, const Camera& camera) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  const double scale_img = 640.0 / std::max(camera.width, camera.height);
  const int w = static_cast<int>(camera.width * scale_img) + 40, h = static_cast<int>(camera.height * scale_img) + 70;
  // One arrow scale for both plots: the largest before-residual is drawn 40 px long.
  double max_res = 1e-9;
  for (size_t i = 0; i < d.x_px.size(); ++i)
    max_res = std::max(max_res, std::hypot(d.dx_before_px[i], d.dy_before_px[i]));
  const double arrow = 40.0 / max_res;
  const double arcsec_per_px = 206264.8 / camera.FocalMeanPx();
  for (int which = 0; which < 2; ++which) {
    cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
    cv::rectangle(
        img, cv::Point(20, 50),
        cv::Point(20 + static_cast<int>(camera.width * scale_img), 50 + static_cast<int>(camera.height * scale_img)),
        cv::Scalar(0, 0, 0), 1);
    const auto& dx = which == 0 ? d.dx_before_px : d.dx_after_px;
    const auto& dy = which == 0 ? d.dy_before_px : d.dy_after_px;
    for (size_t i = 0; i < d.x_px.size(); ++i) {
      const cv::Point2d p(20 + d.x_px[i] * scale_img, 50 + d.y_px[i] * scale_img);
      const cv::Point2d q(p.x + dx[i] * arrow, p.y + dy[i] * arrow);
      cv::arrowedLine(img, p, q, which == 0 ? cv::Scalar(40, 40, 200) : cv::Scalar(40, 140, 40), 1, cv::LINE_AA, 0,
                      0.25);
      cv::circle(img, p, 1, cv::Scalar(0, 0, 0), -1);
    }
    char title[256];
    const double rms = which == 0 ? d.residual_rms_before_arcsec : d.residual_rms_after_arcsec;
    std::snprintf(title, sizeof title, "%s: cause %s, RMS %.2f arcsec, arrow 40 px = %.3f px (%.2f arcsec)",
                  which == 0 ? "before" : "after", d.cause.c_str(), rms, max_res, max_res * arcsec_per_px);
    cv::putText(img, title, cv::Point(10, 30), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    const std::string path = dir + (which == 0 ? "/residuals_before.png" : "/residuals_after.png");
    WritePng(path, img);
  }
}

}  // namespace ssiu
