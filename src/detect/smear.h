// Motion blur (smear) of star images: while the sensor turns at a rate w during the exposure, a star's
// image runs along the path its direction projects to. The on-board processor knows w from the gyros,
// so the detector can expect each star's smear instead of calling it elongated (docs/simulator.md,
// "Motion during the exposure").
//
// Kinematics (conventions.md, dq/dt = 1/2 q * [0, w]): a direction fixed in inertial space is, in
// sensor axes, v(t) = exp(-[w]x t) v(0), t from mid-exposure; the path is that direction projected
// through the camera (distortion included) over t in [-exposure/2, +exposure/2].
#pragma once

#include <optional>

#include "core/camera.h"
#include "core/types.h"

namespace ssiu {

struct ExpectedSmear {
  Vec3 rate_rad_s = Vec3::Zero();  // sensor's angular rate relative to inertial space, sensor axes
  double exposure_s = 0;           // 0: no motion model
  Camera camera;                   // projects the path (must be the frame's camera)
  // Shorter predicted smears are fitted as still images: a smear of L px adds L^2 / 12 px^2 to the
  // PSF's variance along it (0.08 px^2 at 1 px, a 3% wider sigma at 1.2 px), which the fitted sigma
  // absorbs; the smeared fit costs several times the still one.
  double min_px = 1.0;

  bool active() const { return exposure_s > 0 && rate_rad_s.squaredNorm() > 0; }
  // Throws InputError naming the field (a non-finite rate, exposure < 0, a bad camera).
  void Check() const;
  // Check's first problem apart from the camera, as "smear.<field> must be ..." (nullptr: none).
  // Allocates nothing and does not throw.
  const char* Problem() const;
  // Pixel of the direction seen at `pixel` at mid-exposure, `t_s` later (nullopt when behind the camera).
  std::optional<Vec2> PathAt(const Vec2& pixel, double t_s) const;
  // The smear of a star seen (mid-exposure) at `pixel`: its image's end minus its start, in pixels.
  Vec2 DisplacementPx(const Vec2& pixel) const;
};

// A Gaussian PSF (sigma s px) smeared uniformly along a straight segment of `length_px` (both 1 at 0):
// its peak relative to the unsmeared peak, sqrt(2 pi) s / L erf(L / (2 sqrt2 s)), and its
// noise-equivalent area 1 / sum(p^2) relative to the unsmeared 4 pi s^2 (the integral of the squared
// profile is the Gaussian of sigma sqrt2 s averaged over the segment's triangular autocorrelation).
double SmearPeakFactor(double length_px, double sigma_px);
double SmearNeaFactor(double length_px, double sigma_px);

}  // namespace ssiu
