// Multiplicative extended Kalman filter for attitude and gyro bias (Lefferts, Markley & Shuster 1982,
// "Kalman filtering for spacecraft attitude estimation", JGCD 5(5); Markley & Crassidis 2014,
// "Fundamentals of Spacecraft Attitude Determination and Control", sec. 6.2).
// The global attitude is a unit quaternion q (body -> inertial); the filter state is a 3-vector
// attitude error in body axes, q_true = q_est * exp(dtheta), plus the gyro bias error, so the
// covariance stays 6x6 and never sees the quaternion norm constraint.
#pragma once

#include <Eigen/Core>
#include <ostream>

#include "core/types.h"

namespace ssiu {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

// Error-state layout (an index table as in PX4 ekf2's state struct).
struct MekfIndex {
  static constexpr int kAttitude = 0;  // dtheta, rad, body axes
  static constexpr int kBias = 3;      // gyro bias error (true - estimate), rad/s, body axes
  static constexpr int kSize = 6;
};
static_assert(MekfIndex::kBias == MekfIndex::kAttitude + 3 && MekfIndex::kSize == MekfIndex::kBias + 3,
              "MEKF error state is [dtheta(3), dbias(3)]");

struct MekfNoise {
  // Spectral density of the white rate noise of the body rate (rad^2/s), a matrix because the
  // least-squares rate of a skewed unit is not isotropic: sigma_v^2 in Markley & Crassidis eq. 6.93.
  Mat3 rate_white = Mat3::Identity() * 1e-12;
  // Spectral density of the bias random walk (rad^2/s^3): sigma_u^2.
  Mat3 bias_walk = Mat3::Identity() * 1e-18;
};

// What became of an attitude measurement (OnlineFusion::AddAttitude; JSON spelling UpdateStatusName).
enum class UpdateStatus {
  kAccepted,          // "accepted": the filter was updated
  kInitialised,       // "initialised": it started the filter (or restarted it: OnlineFusion::n_restarts)
  kRejectedGate,      // "rejected_nis": NIS beyond the gate
  kRejectedLate,      // "rejected_late": before the filter's time
  kRejectedRepeated,  // "rejected_repeated": the same time as the last measurement
  kRejectedBadInput,  // "rejected_bad_input": a non-finite time, quaternion or covariance
  kRejectedTimeJump,  // "rejected_time_jump": too far beyond the filter's time, not (yet) confirmed
};
const char* UpdateStatusName(UpdateStatus s);
inline std::ostream& operator<<(std::ostream& os, UpdateStatus v) { return os << UpdateStatusName(v); }

struct MekfUpdate {
  UpdateStatus status = UpdateStatus::kRejectedGate;
  bool accepted = false;
  Vec3 residual_rad = Vec3::Zero();  // 2 vec(q_est^-1 * q_meas) before the update, body axes
  double nis = 0;                    // normalised innovation squared (chi^2 with 3 dof)
};

class Mekf {
 public:
  void Init(const Quat& q_inertial_from_body, const Vec3& bias_rad_s, const Mat6& covariance);

  // Propagates over dt with the mean measured body rate w_meas (rad/s). With `coning` the two-sample
  // correction uses the previous step's increment (equal steps); a partial step passes false.
  void Propagate(const Vec3& w_meas_rad_s, double dt_s, const MekfNoise& noise, bool coning = true);

  // Update with a measured attitude q_meas (body -> inertial) whose error, in body axes, has
  // covariance r_body (rad^2). Rejected (state unchanged) when nis > nis_gate.
  MekfUpdate UpdateAttitude(const Quat& q_meas, const Mat3& r_body, double nis_gate);

  // Adds to the bias covariance (after a gyro is dropped, the bias may have jumped).
  void InflateBias(double sigma_rad_s);
  // Moves the bias estimate (rad/s, body axes): the rate solution changed under it (a gyro dropped).
  void ShiftBias(const Vec3& delta_rad_s) { bias_ += delta_rad_s; }
  // Adds to the attitude covariance (a fault has turned the attitude by an unknown angle).
  void InflateAttitude(double sigma_rad);

  const Quat& q() const { return q_; }
  const Vec3& bias() const { return bias_; }
  const Mat6& P() const { return p_; }

  // Error-state transition over dt for the bias-corrected rate w (rad/s), constant over the step
  // (Markley & Crassidis eqs. 6.83-6.84 / Lefferts et al. eq. 187).
  static Mat6 TransitionMatrix(const Vec3& w_rad_s, double dt_s);
  // Discrete process noise (Markley & Crassidis eq. 6.93, with matrix spectral densities).
  static Mat6 ProcessNoise(const MekfNoise& noise, double dt_s);

 private:
  Quat q_ = Quat::Identity();
  Vec3 bias_ = Vec3::Zero();
  Mat6 p_ = Mat6::Identity();
  Vec3 prev_increment_ = Vec3::Zero();
  bool has_prev_ = false;
};

}  // namespace ssiu
