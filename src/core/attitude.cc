#include "core/attitude.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace ssiu {

Vec3 UnitFromRaDec(double ra_rad, double dec_rad) {
  const double cd = std::cos(dec_rad);
  return {cd * std::cos(ra_rad), cd * std::sin(ra_rad), std::sin(dec_rad)};
}

void RaDecFromUnit(const Vec3& u, double* ra_rad, double* dec_rad) {
  const Vec3 n = u.normalized();
  double ra = std::atan2(n.y(), n.x());
  if (ra < 0) ra += 2 * kPi;
  *ra_rad = ra;
  *dec_rad = std::asin(std::clamp(n.z(), -1.0, 1.0));
}

Quat QuatFromRaDecRoll(double ra_rad, double dec_rad, double roll_rad) {
  // Columns of R(ra, dec, 0) are the sensor axes in inertial coordinates:
  // X = west = -east, Y = -north, Z = boresight (east, north: local tangent basis at the boresight).
  const Vec3 z = UnitFromRaDec(ra_rad, dec_rad);
  const Vec3 east(-std::sin(ra_rad), std::cos(ra_rad), 0.0);
  const Vec3 north(-std::sin(dec_rad) * std::cos(ra_rad), -std::sin(dec_rad) * std::sin(ra_rad), std::cos(dec_rad));
  Mat3 r0;
  r0.col(0) = -east;
  r0.col(1) = -north;
  r0.col(2) = z;
  const Quat q0(r0);
  const Quat qz(Eigen::AngleAxisd(roll_rad, Vec3::UnitZ()));
  return (q0 * qz).normalized();
}

RaDecRoll RaDecRollFromQuat(const Quat& q) {
  const Mat3 r = q.normalized().toRotationMatrix();
  RaDecRoll out;
  RaDecFromUnit(r.col(2), &out.ra_rad, &out.dec_rad);
  // Rz(roll) = R0^T R; its (0,0), (1,0) entries are cos, sin of roll.
  const Mat3 r0 = QuatFromRaDecRoll(out.ra_rad, out.dec_rad, 0.0).toRotationMatrix();
  const Mat3 rz = r0.transpose() * r;
  double roll = std::atan2(rz(1, 0), rz(0, 0));
  if (roll < 0) roll += 2 * kPi;
  out.roll_rad = roll;
  return out;
}

std::array<double, 4> ToWxyz(const Quat& q_in) {
  Quat q = q_in.normalized();
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  return {q.w(), q.x(), q.y(), q.z()};
}

Quat FromWxyz(double w, double x, double y, double z, const char* what) {
  const double n = std::sqrt(w * w + x * x + y * y + z * z);
  if (!std::isfinite(n) || n < 1e-12) {
    throw InputError(std::string(what) + ": not a valid quaternion (zero or non-finite)");
  }
  return Quat(w / n, x / n, y / n, z / n);
}

Quat QuatFromUniform(double u1, double u2, double u3) {
  // K. Shoemake, "Uniform random rotations", Graphics Gems III, 1992.
  const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
  return Quat(b * std::cos(2 * kPi * u3), a * std::sin(2 * kPi * u2), a * std::cos(2 * kPi * u2),
              b * std::sin(2 * kPi * u3))
      .normalized();
}

double AttitudeErrorRad(const Quat& q_est, const Quat& q_true) {
  const Quat d = (q_est.normalized() * q_true.normalized().conjugate());
  const double v = d.vec().norm();
  return 2.0 * std::atan2(v, std::abs(d.w()));
}

AttitudeErrorSplit SplitAttitudeError(const Quat& q_est, const Quat& q_true) {
  AttitudeErrorSplit s;
  s.total_rad = AttitudeErrorRad(q_est, q_true);
  const Vec3 z_est = q_est.normalized() * Vec3::UnitZ();
  const Vec3 z_true = q_true.normalized() * Vec3::UnitZ();
  s.cross_rad = std::atan2(z_est.cross(z_true).norm(), z_est.dot(z_true));
  // Roll: rotation about the boresight in the sensor frame, from the twist part of conj(q_true)*q_est.
  const Quat d = q_true.normalized().conjugate() * q_est.normalized();
  s.roll_rad = 2.0 * std::atan2(d.z(), d.w());
  if (s.roll_rad > kPi) s.roll_rad -= 2 * kPi;
  if (s.roll_rad < -kPi) s.roll_rad += 2 * kPi;
  return s;
}

}  // namespace ssiu
