#include "groundtest/stand.h"

#include <cmath>
#include <vector>

#include "attitude/quest.h"

namespace ssiu {

Quat StandRotation(double az_rad, double el_rad, double rot_rad) {
  const Quat q = Quat(Eigen::AngleAxisd(az_rad, Vec3::UnitY())) * Quat(Eigen::AngleAxisd(el_rad, Vec3::UnitX())) *
                 Quat(Eigen::AngleAxisd(rot_rad, Vec3::UnitZ()));
  return q.normalized();
}

Vec3 ApparentDirection(const Mask& m, const PlatePose& pose, double x_mm, double y_mm) {
  const Vec3 p = pose.r_c_from_p * Vec3(x_mm, y_mm, 0) + pose.t_c_mm;
  return Vec3(p.x(), p.y(), p.z() + m.collimator_focal_mm).normalized();
}

Quat MaskRotation(const Mask& m, const PlatePose& pose) {
  std::vector<WahbaObservation> obs;
  auto add = [&](double x, double y) {
    WahbaObservation o;
    o.b_sensor = m.DirectionOf(x, y);
    o.r_inertial = ApparentDirection(m, pose, x, y);
    o.sigma_rad = 1e-5;
    obs.push_back(o);
  };
  for (const auto& h : m.holes) add(h.x_mm, h.y_mm);
  // A grid over the field as well, so that the answer does not depend on how many stars there are.
  for (int i = -2; i <= 2; ++i)
    for (int j = -2; j <= 2; ++j) add(i * m.field_half_x_mm / 2, j * m.field_half_y_mm / 2);
  return SolveDavenport(obs).normalized();  // maps b (M) to r (C): q_C_from_M
}

Vec3 RotationVector(const Quat& q_in) {
  Quat q = q_in.normalized();
  if (q.w() < 0) q.coeffs() *= -1;
  const double s = q.vec().norm();
  if (s < 1e-15) return 2 * q.vec();
  return q.vec() * (2 * std::atan2(s, q.w()) / s);
}

}  // namespace ssiu
