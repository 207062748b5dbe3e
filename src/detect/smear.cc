#include "detect/smear.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "core/error.h"

namespace ssiu {

const char* ExpectedSmear::Problem() const {
  if (!rate_rad_s.allFinite()) return "smear.rate_rad_s must be finite";
  if (!(std::isfinite(exposure_s) && exposure_s >= 0 && exposure_s < 100)) return "smear.exposure_s must be in [0, 100)";
  if (!(std::isfinite(min_px) && min_px >= 0)) return "smear.min_px must be >= 0";
  return nullptr;
}

void ExpectedSmear::Check() const {
  if (const char* p = Problem()) throw InputError(std::string("DetectOptions: ") + p);
  if (!active()) return;
  camera.Check("DetectOptions: smear.camera");
}

std::optional<Vec2> ExpectedSmear::PathAt(const Vec2& pixel, double t_s) const {
  const Vec3 v = camera.Unproject(pixel);
  const double w = rate_rad_s.norm();
  if (w == 0 || t_s == 0) return camera.Project(v);
  return camera.Project(Eigen::AngleAxisd(-w * t_s, rate_rad_s / w) * v);
}

Vec2 ExpectedSmear::DisplacementPx(const Vec2& pixel) const {
  if (!active()) return Vec2::Zero();
  const auto a = PathAt(pixel, -0.5 * exposure_s), b = PathAt(pixel, 0.5 * exposure_s);
  if (!a || !b) return Vec2::Zero();
  return *b - *a;
}

double SmearPeakFactor(double length_px, double sigma_px) {
  const double l = std::abs(length_px), s = sigma_px;
  if (l < 1e-6 * s) return 1.0;
  return std::sqrt(2 * kPi) * s / l * std::erf(l / (2 * std::sqrt(2.0) * s));
}

double SmearNeaFactor(double length_px, double sigma_px) {
  const double l = std::abs(length_px), s2 = std::sqrt(2.0) * sigma_px;
  if (l < 1e-6 * sigma_px) return 1.0;
  // int p^2 dx (1-D) = int_{-L}^{L} (1/L)(1 - |u|/L) N(u; 0, s2^2) du, closed form with x = L / s2.
  const double x = l / s2;
  const double phi_half = 0.5 * std::erf(x / std::sqrt(2.0));  // Phi(x) - 1/2
  const double integral = 2.0 / l * (phi_half - s2 / (l * std::sqrt(2 * kPi)) * (1.0 - std::exp(-0.5 * x * x)));
  const double unsmeared = 1.0 / (s2 * std::sqrt(2 * kPi));
  return unsmeared / integral;
}

}  // namespace ssiu
