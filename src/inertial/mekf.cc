#include "inertial/mekf.h"

#include <Eigen/Dense>
#include <cmath>

#include "inertial/propagate.h"

namespace ssiu {

void Mekf::Init(const Quat& q, const Vec3& bias, const Mat6& covariance) {
  q_ = q.normalized();
  bias_ = bias;
  p_ = covariance;
  has_prev_ = false;
}

Mat6 Mekf::TransitionMatrix(const Vec3& w, double dt) {
  // d(dtheta)/dt = -[w x] dtheta - dbias ;  d(dbias)/dt = 0.
  const double n = w.norm();
  const double th = n * dt;
  const Mat3 wx = Skew(w);
  const Mat3 wx2 = wx * wx;
  const Mat3 eye = Mat3::Identity();
  Mat3 phi11, phi12;
  if (th < 1e-5) {  // series of the closed form; the next terms are below 1e-20 relative
    phi11 = eye - wx * dt + wx2 * (dt * dt / 2);
    phi12 = -eye * dt + wx * (dt * dt / 2) - wx2 * (dt * dt * dt / 6);
  } else {
    phi11 = eye - wx * (std::sin(th) / n) + wx2 * ((1 - std::cos(th)) / (n * n));
    phi12 = wx * ((1 - std::cos(th)) / (n * n)) - eye * dt - wx2 * ((th - std::sin(th)) / (n * n * n));
  }
  Mat6 f = Mat6::Identity();
  f.block<3, 3>(MekfIndex::kAttitude, MekfIndex::kAttitude) = phi11;
  f.block<3, 3>(MekfIndex::kAttitude, MekfIndex::kBias) = phi12;
  return f;
}

Mat6 Mekf::ProcessNoise(const MekfNoise& noise, double dt) {
  Mat6 q = Mat6::Zero();
  const Mat3& v = noise.rate_white;
  const Mat3& u = noise.bias_walk;
  q.block<3, 3>(MekfIndex::kAttitude, MekfIndex::kAttitude) = v * dt + u * (dt * dt * dt / 3);
  q.block<3, 3>(MekfIndex::kAttitude, MekfIndex::kBias) = -u * (dt * dt / 2);
  q.block<3, 3>(MekfIndex::kBias, MekfIndex::kAttitude) = -u * (dt * dt / 2);
  q.block<3, 3>(MekfIndex::kBias, MekfIndex::kBias) = u * dt;
  return q;
}

void Mekf::Propagate(const Vec3& w_meas, double dt, const MekfNoise& noise, bool coning) {
  const Vec3 w = w_meas - bias_;
  const Vec3 a = w * dt;
  const Vec3 phi = (coning && has_prev_) ? ConingRotationVector(prev_increment_, a) : a;
  q_ = (q_ * QuatFromRotationVector(phi)).normalized();
  if (coning) {
    prev_increment_ = a;
    has_prev_ = true;
  }
  const Mat6 f = TransitionMatrix(w, dt);
  p_ = f * p_ * f.transpose() + ProcessNoise(noise, dt);
  p_ = 0.5 * (p_ + p_.transpose());
}

const char* UpdateStatusName(UpdateStatus s) {
  switch (s) {
    case UpdateStatus::kAccepted:
      return "accepted";
    case UpdateStatus::kInitialised:
      return "initialised";
    case UpdateStatus::kRejectedGate:
      return "rejected_nis";
    case UpdateStatus::kRejectedLate:
      return "rejected_late";
    case UpdateStatus::kRejectedRepeated:
      return "rejected_repeated";
    case UpdateStatus::kRejectedBadInput:
      return "rejected_bad_input";
    case UpdateStatus::kRejectedTimeJump:
      return "rejected_time_jump";
  }
  return "rejected_bad_input";
}

MekfUpdate Mekf::UpdateAttitude(const Quat& q_meas, const Mat3& r_body, double nis_gate) {
  MekfUpdate out;
  // Measurement model: q_meas = q_true * exp(v), so dz = log(q_est^-1 q_meas) = dtheta + v, H = [I 0].
  out.residual_rad = RotationVectorFromQuat(q_.conjugate() * q_meas);
  const Mat3 s = p_.block<3, 3>(0, 0) + r_body;
  const Mat3 s_inv = s.inverse();
  out.nis = out.residual_rad.dot(s_inv * out.residual_rad);
  if (!(out.nis <= nis_gate)) return out;
  const Eigen::Matrix<double, 6, 3> k = p_.block<6, 3>(0, 0) * s_inv;
  const Vec6 dx = k * out.residual_rad;
  // Reset: fold the attitude error into the quaternion, the bias error into the bias (the error
  // state returns to zero; Markley & Crassidis eq. 6.27).
  q_ = (q_ * QuatFromRotationVector(dx.segment<3>(MekfIndex::kAttitude))).normalized();
  bias_ += dx.segment<3>(MekfIndex::kBias);
  // Joseph form keeps P symmetric positive definite.
  Mat6 ikh = Mat6::Identity();
  ikh.block<6, 3>(0, 0) -= k;
  p_ = ikh * p_ * ikh.transpose() + k * r_body * k.transpose();
  p_ = 0.5 * (p_ + p_.transpose());
  out.accepted = true;
  out.status = UpdateStatus::kAccepted;
  return out;
}

void Mekf::InflateBias(double sigma) {
  p_.block<3, 3>(MekfIndex::kBias, MekfIndex::kBias) += Mat3::Identity() * sigma * sigma;
}

void Mekf::InflateAttitude(double sigma) {
  p_.block<3, 3>(MekfIndex::kAttitude, MekfIndex::kAttitude) += Mat3::Identity() * sigma * sigma;
}

}  // namespace ssiu
