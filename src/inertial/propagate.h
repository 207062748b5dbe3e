// Attitude propagation with gyro angle increments (strapdown kinematics, conventions.md):
// q is body -> inertial (Hamilton), dq/dt = 1/2 q * [0, w_body], w the body rate relative to inertial
// space in body axes. Over a step the attitude advances by the rotation vector phi of the body:
// q_k = q_{k-1} * exp(phi), exact when phi is the true rotation vector (Bortz 1971).
#pragma once

#include "core/types.h"

namespace ssiu {

// exp: rotation vector (rad) -> unit quaternion; series near zero.
Quat QuatFromRotationVector(const Vec3& phi);
// log: unit quaternion -> rotation vector (rad) of angle in [0, pi].
Vec3 RotationVectorFromQuat(const Quat& q);
// Skew-symmetric cross-product matrix [v x].
Mat3 Skew(const Vec3& v);

// Two-sample coning correction for equal intervals (Savage 1998, "Strapdown inertial navigation
// integration algorithm design part 1", eq. 38 for a linearly varying rate):
//   phi = a2 + 1/12 a1 x a2, with a1, a2 the previous and current angle increments (rad).
Vec3 ConingRotationVector(const Vec3& increment_prev, const Vec3& increment);

// Rotation vector over one step for a rate varying linearly from w0 to w1 (rad/s) over dt:
//   phi = dt (w0 + w1)/2 + dt^2/12 w0 x w1 (the Bortz equation integrated to second order).
Vec3 RotationVectorLinearRate(const Vec3& w0, const Vec3& w1, double dt);

// Integrates gyro angle increments into an attitude with the two-sample coning correction.
class AttitudePropagator {
 public:
  explicit AttitudePropagator(const Quat& q_inertial_from_body) : q_(q_inertial_from_body.normalized()) {}
  // One gyro sample: w_mean is the mean body rate over the step (rad/s), as an FOG outputs it.
  void Step(const Vec3& w_mean_rad_s, double dt_s);
  const Quat& q() const { return q_; }

 private:
  Quat q_;
  Vec3 prev_increment_ = Vec3::Zero();
  bool has_prev_ = false;
};

}  // namespace ssiu
