// Star-inertial fusion sample by sample, as the unit's processor runs it: each gyro sample propagates
// the MEKF and feeds fault detection, each attitude measurement (a star-tracker solution) updates it.
// The same estimator as the batch Fuse() (fuse.h): the MEKF (mekf.h), the parity monitor and the
// star-rate isolator (fdi.h) in the same order, so that on a log whose star times fall on gyro
// sample times both give the same answer (tests/sim/mission_test.cc checks this).
//
//   OnlineFusion f(unit, FuseOptions{});
//   f.AddGyro(t_k, g_dph);                    // every gyro sample, in time order
//   f.AddAttitude(t_j, q_body, r_body_rad2);  // every star solution (t_j >= last gyro time)
//   f.q(), f.P(), f.bias_rad_s(), f.faults()
#pragma once

#include <deque>
#include <utility>
#include <vector>

#include "core/types.h"
#include "inertial/fdi.h"
#include "inertial/fuse.h"
#include "inertial/gyro_unit.h"
#include "inertial/mekf.h"

namespace ssiu {

class OnlineFusion {
 public:
  // Raw gyro outputs of `unit` (its size, axes and noise figures; the sample interval is
  // 1 / unit.rate_hz). InputError for a bad unit or bad options.
  OnlineFusion(const GyroUnit& unit, const FuseOptions& options);

  // One gyro sample: the mean outputs (deg/h) over (t_prev, t_s]. Ignored before the first attitude
  // measurement (nothing to start from) and when not later than the current time.
  void AddGyro(double t_s, const GyroVec& g_dph);

  // An attitude measurement (body -> inertial) at t_s with error covariance r_body (rad^2, body axes).
  // The first one initialises the filter. A measurement after the last gyro sample is reached by
  // propagating with the last gyro rate (zero-order hold, the on-board case of a frame arriving before
  // the gyro sample that covers it); one before the current time is refused (returned not accepted).
  MekfUpdate AddAttitude(double t_s, const Quat& q_inertial_from_body, const Mat3& r_body);

  bool initialised() const { return initialised_; }
  double t_s() const { return t_cur_; }
  const Quat& q() const { return filter_.q(); }
  const Mat6& P() const { return filter_.P(); }
  const Vec3& bias_rad_s() const { return filter_.bias(); }
  const std::vector<FaultEvent>& faults() const { return faults_; }
  // 1 sigma of the attitude error about body x, y, z (rad) and of the body bias (deg/h), from P().
  Vec3 attitude_sigma_rad() const;
  Vec3 bias_sigma_dph() const;
  // Whether the attitude can be trusted now: "ok"; "degraded" while a fault is detected but not
  // isolated (the covariance is opened to cover it) and for policy.settle_after_isolation_s after its
  // isolation (the bias re-converging on the remaining gyros), or once a faulty gyro had to stay in
  // use (three left, its fault compensated), or (policy.degraded_without_spare) once an isolation left
  // no spare gyro; "failed" when degraded and no star measurement has been
  // accepted for policy.failed_after_s (nothing bounds the drift); "failed" before the first measurement.
  FusionStatus Status() const;
  // The default policies (FusionPolicy in fuse.h holds them and the options may change them).
  static constexpr double kFailedAfterS = FusionPolicy{}.failed_after_s;
  static constexpr double kSettleS = FusionPolicy{}.settle_after_isolation_s;
  std::vector<int> GyrosInUse() const;  // 1-based
  long n_gyro_samples() const { return n_gyro_; }
  long n_updates() const { return n_used_; }
  long n_rejected() const { return n_rejected_; }
  long n_late() const { return n_late_; }

 private:
  void PropagateTo(double t_s, const Vec3& w, const GyroVec& g, bool coning);
  void Isolate(int gi, double t, const char* method, const GyroVec& resid, double fault_dph);
  void SetSolver();
  void OnDetection(double t, const std::string& test, double onset_s, double parity_jump_dph);
  void OpenCovarianceWhileUnresolved();
  void FloorBias(double sigma_rad_s);
  Vec3 BiasAt(double t_s) const;
  // b_before: the bias estimate at the fault's onset (BiasAt), restored when the fault is tracked.
  void Compensate(int gi, double t, const Vec3& b_before);
  void RefitTrackedFault(double t);
  Vec3 RateDph(const GyroVec& g) const { return solver_.Solve(g - correction_ - dyn_); }

  GyroUnit unit_;
  FuseOptions opt_;
  GyroAxes axes_;
  GyroVec arw_, sample_sigma_dph_, correction_;
  std::vector<bool> use_;
  RateSolver solver_;
  MekfNoise noise_;
  double dt_nominal_ = 0.01;
  bool fdi_on_ = false;
  ParityMonitor monitor_;
  StarRateIsolator isolator_;
  bool isolating_ = false;
  bool compensated_ = false;                             // a faulty gyro stays in use, its fault subtracted
  GyroVec fit_step_, fit_ramp_;                          // parity fit since onset at the pending detection
  GyroParity fit_v_;                                     // the parity matrix it was made with
  double innov_s_ = 0, innov_zero_t_ = 0, innov_h_ = 0;  // star-innovation CUSUM (no parity left)
  // A faulty gyro that stays in use (no spare) is compensated by the step + ramp fitted to its
  // star-rate residual, refitted at every star sample, so that a ramp is followed as one fault.
  int tracked_ = -1;          // that gyro (0-based), -1: none
  size_t tracked_event_ = 0;  // its event in faults_
  StarRateIsolator tracker_;  // its star rates since detection (fed the raw outputs)
  FaultFit track_fit_;        // the latest fit, made at track_fit_t_
  double track_fit_t_ = 0, track_from_s_ = 0, track_onset0_s_ = 0;
  bool track_reporting_ = false;  // the event still takes each new fit (its window reaches the onset)
  GyroVec dyn_;                   // the compensation now (deg/h; non-zero on the tracked gyro only)
  double t_last_accepted_ = 0;
  double t_settled_ = -1;  // degraded until then after an isolation (the filter re-converging)
  std::deque<std::pair<double, Vec3>> bias_history_;  // (t, bias rad/s), one per accepted update

  Mekf filter_;
  bool initialised_ = false;
  double t_cur_ = 0, t_last_st_ = 0;
  bool have_gyro_ = false;
  double t_last_gyro_ = 0;
  Vec3 w_last_ = Vec3::Zero();
  GyroVec g_last_;
  int consecutive_rejects_ = 0;
  long n_gyro_ = 0, n_used_ = 0, n_rejected_ = 0, n_late_ = 0;
  std::vector<FaultEvent> faults_;
};

}  // namespace ssiu
