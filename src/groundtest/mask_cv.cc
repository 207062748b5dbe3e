// WriteMaskPng of mask.h (OpenCV drawing), in the OpenCV edge module (core/opencv_edge.h).
#include <apriltag/apriltag.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <opencv2/imgproc.hpp>

#include "core/attitude.h"
#include "core/error.h"
#include "core/image_cv.h"
#include "core/output.h"
#include "groundtest/apriltag_family.h"
#include "groundtest/mask.h"

namespace ssiu {

void WriteMaskPng(const Mask& m, const std::string& path, double dpi) {
  if (!(dpi >= 10 && dpi <= 4800)) throw InputError("--dpi", "must be in [10, 4800]");
  const double px_per_mm = dpi / 25.4;
  const double side_px = std::ceil(2 * m.plate_half_mm * px_per_mm);
  if (side_px > 30000)
    throw InputError("--dpi", std::to_string(static_cast<long>(side_px)) +
                                  " px across the plate is too large for a PNG; lower --dpi or use mask.svg");
  const int n = static_cast<int>(side_px);
  cv::Mat img(n, n, CV_8UC1, cv::Scalar(0));
  auto to_px = [&](double mm) { return (mm + m.plate_half_mm) * px_per_mm - 0.5; };
  constexpr int kShift = 4;  // sub-pixel drawing
  constexpr double kScale = 1 << kShift;
  for (const auto& h : m.holes) {
    const double r = std::max(0.5, h.diameter_mm / 2 * px_per_mm);  // at least one dot
    cv::circle(img,
               cv::Point(static_cast<int>(std::lround(to_px(h.x_mm) * kScale)),
                         static_cast<int>(std::lround(to_px(h.y_mm) * kScale))),
               static_cast<int>(std::lround(r * kScale)), cv::Scalar(255), cv::FILLED, cv::LINE_AA, kShift);
  }
  for (const auto& t : m.tags) {
    int cells = 0;
    const std::vector<uint8_t> p = TagPattern(m.tag_family, t.id, &cells);
    const double c = t.size_mm / groundtest_internal::CreateFamily(m.tag_family)->width_at_border;  // mask.cc TagCellMm
    const double x0 = t.x_mm - cells * c / 2, y0 = t.y_mm - cells * c / 2;
    for (int r = 0; r < cells; ++r)
      for (int k = 0; k < cells; ++k) {
        const int xa = static_cast<int>(std::lround((x0 + k * c + m.plate_half_mm) * px_per_mm));
        const int xb = static_cast<int>(std::lround((x0 + (k + 1) * c + m.plate_half_mm) * px_per_mm));
        const int ya = static_cast<int>(std::lround((y0 + r * c + m.plate_half_mm) * px_per_mm));
        const int yb = static_cast<int>(std::lround((y0 + (r + 1) * c + m.plate_half_mm) * px_per_mm));
        cv::rectangle(img, cv::Rect(xa, ya, xb - xa, yb - ya), cv::Scalar(p[static_cast<size_t>(r) * cells + k]),
                      cv::FILLED);
      }
  }
  const std::string bytes = PngBytes(img, 12);
  std::vector<uchar> png(bytes.begin(), bytes.end());
  if (png.size() < 33) throw InputError(path, "PNG encoding failed");
  // The print scale as a pHYs chunk (PNG 1.2 spec, section 4.2.4.2: pixels per metre, unit 1), right
  // after IHDR (8-byte signature + 25-byte IHDR chunk), so that a print shop or a viewer reproduces the
  // plate at 1:1.
  const uint32_t ppm = static_cast<uint32_t>(std::lround(dpi / 0.0254));
  std::vector<uchar> chunk = {0, 0, 0, 9, 'p', 'H', 'Y', 's'};
  for (int k = 0; k < 2; ++k)
    for (int b = 3; b >= 0; --b) chunk.push_back(static_cast<uchar>(ppm >> (8 * b)));
  chunk.push_back(1);
  uint32_t crc = 0xffffffffu;  // CRC-32 (ISO 3309) over type and data
  for (size_t i = 4; i < chunk.size(); ++i) {
    crc ^= chunk[i];
    for (int b = 0; b < 8; ++b) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  crc ^= 0xffffffffu;
  for (int b = 3; b >= 0; --b) chunk.push_back(static_cast<uchar>(crc >> (8 * b)));
  png.insert(png.begin() + 33, chunk.begin(), chunk.end());
  WriteFileAtomic(path, std::string(png.begin(), png.end()));
}

}  // namespace ssiu
