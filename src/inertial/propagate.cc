#include "inertial/propagate.h"

#include <cmath>

namespace ssiu {

Quat QuatFromRotationVector(const Vec3& phi) {
  const double a = phi.norm();
  const double half = 0.5 * a;
  // sin(a/2)/a by its Taylor series below 1e-4 rad (error < 1e-17).
  const double s = a < 1e-4 ? 0.5 - a * a / 48.0 : std::sin(half) / a;
  Quat q(std::cos(half), s * phi.x(), s * phi.y(), s * phi.z());
  return q.normalized();
}

Vec3 RotationVectorFromQuat(const Quat& q_in) {
  Quat q = q_in.normalized();
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const Vec3 v = q.vec();
  const double s = v.norm();
  if (s < 1e-12) return 2.0 * v;
  const double a = 2.0 * std::atan2(s, q.w());
  return v * (a / s);
}

Mat3 Skew(const Vec3& v) {
  Mat3 m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Vec3 ConingRotationVector(const Vec3& increment_prev, const Vec3& increment) {
  return increment + increment_prev.cross(increment) / 12.0;
}

Vec3 RotationVectorLinearRate(const Vec3& w0, const Vec3& w1, double dt) {
  return 0.5 * dt * (w0 + w1) + dt * dt / 12.0 * w0.cross(w1);
}

void AttitudePropagator::Step(const Vec3& w_mean_rad_s, double dt_s) {
  const Vec3 a = w_mean_rad_s * dt_s;
  const Vec3 phi = has_prev_ ? ConingRotationVector(prev_increment_, a) : a;
  q_ = (q_ * QuatFromRotationVector(phi)).normalized();
  prev_increment_ = a;
  has_prev_ = true;
}

}  // namespace ssiu
