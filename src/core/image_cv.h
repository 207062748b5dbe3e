// PNG output of a cv::Mat, for the OpenCV edge (core/opencv_edge.h) and tests: the pixels handed to
// core/image.h's writers, which need no OpenCV.
#pragma once

#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>

#include "core/image.h"

namespace ssiu {

// 8/16-bit, 1-4 channels (grey, BGR, BGRA); std::invalid_argument for another type.
inline std::string PngBytes(const cv::Mat& m, int level = 6) {
  const int depth = m.depth() == CV_8U ? 8 : m.depth() == CV_16U ? 16 : 0;
  if (depth == 0 || m.dims != 2 || m.empty())
    throw std::invalid_argument("PngBytes: only 8/16-bit images of 1-4 channels");
  return PngBytes(m.data, m.cols, m.rows, m.channels(), depth, m.step[0], level);
}

// InputError naming the file when it cannot be written, has an extension other than .png, or the type
// cannot be encoded.
inline void WritePng(const std::string& path, const cv::Mat& m) {
  const int depth = m.depth() == CV_8U ? 8 : m.depth() == CV_16U ? 16 : 0;
  WritePng(path, m.data, m.cols, m.rows, m.channels(), m.dims == 2 && !m.empty() ? depth : 0, m.step[0]);
}

}  // namespace ssiu
