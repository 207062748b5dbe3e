#include "attitude/overlay.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <set>
#include <vector>

#include "core/error.h"
#include "core/image_cv.h"

namespace ssiu {

void WriteSolveOverlay(const std::string& path, const ImageView& image, const Camera& camera, const StarIdentifier& id,
                       const SolveResult& r) {
  // Stretch: median background to 1st..99.8th percentile of the pixel values.
  std::vector<uint16_t> v;
  v.reserve(static_cast<size_t>(image.width) * image.height / 16 + 1);
  for (int y = 0; y < image.height; y += 4)
    for (int x = 0; x < image.width; x += 4) v.push_back(image.at(x, y));
  std::sort(v.begin(), v.end());
  const double lo = v.empty() ? 0 : v[v.size() / 100],
               hi = v.empty() ? 1 : std::max<double>(v[v.size() * 998 / 1000], lo + 1);
  cv::Mat img(image.height, image.width, CV_8UC3);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const auto g = static_cast<uint8_t>(std::clamp((image.at(x, y) - lo) / (hi - lo) * 255.0, 0.0, 255.0));
      img.at<cv::Vec3b>(y, x) = {g, g, g};
    }
  const cv::Scalar green(0, 220, 0), yellow(0, 220, 220), red(0, 0, 255), blue(255, 128, 0);
  auto pt = [](double x, double y) {
    return cv::Point(static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y)));
  };
  std::set<int> matched;
  for (const auto& m : r.identification.matches) matched.insert(m.centroid);
  for (size_t i = 0; i < r.centroids.size(); ++i)
    if (!matched.count(static_cast<int>(i)))
      cv::circle(img, pt(r.centroids[i].x_px, r.centroids[i].y_px), 7, yellow, 1);
  for (const auto& rj : r.detections.rejected) {
    const cv::Point p = pt(rj.x_px, rj.y_px);
    cv::drawMarker(img, p, red, cv::MARKER_TILTED_CROSS, 10, 1);
    cv::putText(img, RejectReasonName(rj.reason), p + cv::Point(6, -6), cv::FONT_HERSHEY_PLAIN, 0.8, red, 1);
  }
  if (r.status == SolveStatus::kSolved) {
    std::set<int> matched_stars;
    for (const auto& m : r.identification.matches) matched_stars.insert(m.star);
    const Camera cam = FittedCamera(camera, r.identification);
    const Mat3 rot = r.attitude.q_inertial_from_sensor.toRotationMatrix();
    for (int s : id.StarsWithin(rot.col(2), cam.FovDiagRad() / 2)) {
      if (matched_stars.count(s)) continue;
      const auto p = cam.Project(rot.transpose() * id.catalog().stars[s].unit);
      if (p && cam.InImage(*p)) cv::rectangle(img, pt((*p)[0] - 5, (*p)[1] - 5), pt((*p)[0] + 5, (*p)[1] + 5), blue, 1);
    }
    for (const auto& m : r.identification.matches) {
      const cv::Point p = pt(m.x_px, m.y_px);
      cv::circle(img, p, 9, green, 2);
      cv::putText(img, std::to_string(m.star_id), p + cv::Point(10, 14), cv::FONT_HERSHEY_PLAIN, 1.0, green, 1);
    }
  }
  const std::string title = SolveStatusName(r.status) + ("  " + r.message);
  cv::putText(img, title, cv::Point(10, 24), cv::FONT_HERSHEY_SIMPLEX, 0.6,
              r.status == SolveStatus::kSolved ? green : red, 2);
  cv::putText(img,
              "green: matched (star_id)  yellow: unmatched detection  blue: predicted, not detected  red: rejected",
              cv::Point(10, image.height - 12), cv::FONT_HERSHEY_PLAIN, 1.0, cv::Scalar(255, 255, 255), 1);
  WritePng(path, img);
}

}  // namespace ssiu
