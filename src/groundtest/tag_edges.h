// Internal: sub-pixel tag corners from a model fit of the tag's four outer edges (reference.cc).
//
// libapriltag's own edge refinement takes the gradient centroid of nearest-pixel samples +/-2 px
// across an edge at 16 points per side: its corners carry pixel-phase errors of ~0.1 px, ten times
// what the photo's noise allows. Here every pixel within a band around each side is fitted with a
// blurred step, I = a + b Phi((n . (p - p0) - delta) / s) (Gauss-Newton, 5 parameters), the maximum-
// likelihood line under Gaussian pixel noise; its covariance sigma_n^2 (J^T J)^-1 is the accuracy the
// pixel noise allows (the Cramer-Rao bound of this model). Adjacent lines intersect in the corners.
#pragma once

#include <array>
#include <cstdint>

#include "core/camera.h"
#include "core/types.h"

namespace ssiu::groundtest_internal {

struct TagCornerFit {
  bool ok = false;
  std::array<Vec2, 4> corners_px;  // undistorted pixel coordinates (pinhole: cx + f X/Z), libapriltag's order
  Eigen::Matrix<double, 8, 8> covariance =
      Eigen::Matrix<double, 8, 8>::Zero();  // of (x0,y0,...,x3,y3), px^2, per unit noise
  double rss_dn2 = 0;                       // sum of squared fit residuals over the four edges
  int pixels = 0;                           // pixels fitted
  int parameters = 0;                       // parameters fitted (5 per edge)
};

// `corners_px`: libapriltag's corners in the photo (ssiu pixel convention, distorted). The covariance
// is for a pixel noise of 1 DN: multiply by sigma_n^2.
TagCornerFit FitTagCorners(const uint8_t* pixels, int width, int height, const Camera& camera,
                           const std::array<Vec2, 4>& corners_px, int border_cells);

// Distorted pixel -> undistorted (pinhole) pixel coordinates of the same camera.
Vec2 UndistortPixel(const Camera& camera, const Vec2& px);

}  // namespace ssiu::groundtest_internal
