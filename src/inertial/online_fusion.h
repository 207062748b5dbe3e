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
//
// Flight rules (docs/inertial.md "Bad inputs"): after construction AddGyro allocates nothing and
// neither call throws; what a call did with its input is its status (GyroSampleStatus,
// MekfUpdate::status), counted per kind; no input can make the state non-finite, and if it ever is
// the filter restarts from the next star solution (Status() says "failed" until then).
#pragma once

#include <array>
#include <ostream>
#include <utility>
#include <vector>

#include "core/types.h"
#include "inertial/fdi.h"
#include "inertial/fuse.h"
#include "inertial/gyro_unit.h"
#include "inertial/mekf.h"

namespace ssiu {

// What AddGyro did with a sample (JSON spelling GyroSampleStatusName).
enum class GyroSampleStatus {
  kAccepted = 0,         // "accepted"
  kAcceptedPartial,      // "accepted_partial": an output unusable (NaN/inf or beyond policy.max_gyro_output_dph),
                         // the rate from the other gyros in use
  kAcceptedAfterGap,     // "accepted_after_gap": confirms a time jump; the attitude restarts from the next star fix
  kRejectedNonFinite,    // "rejected_non_finite": NaN/inf outputs and the rest give no rate: the last rate is
                         // held over the interval
  kRejectedOutOfRange,   // "rejected_out_of_range": the same for outputs beyond the range
  kRejectedOutOfOrder,   // "rejected_out_of_order": before the last sample (state unchanged)
  kRejectedRepeated,     // "rejected_repeated": the last sample's time again (state unchanged)
  kRejectedBadTime,      // "rejected_bad_time": a NaN/inf time (state unchanged)
  kRejectedWrongSize,    // "rejected_wrong_size": not one output per gyro (state unchanged)
  kRejectedTimeJump,     // "rejected_time_jump": more than policy.max_gyro_gap_s after the last sample; taken
                         // if the next sample follows it (state unchanged otherwise)
  kAcceptedTimeReset,    // "accepted_time_reset": the last of policy.resync_after_samples out-of-order samples
                         // in a row: their time taken, the attitude restarts from the next star fix
};
constexpr int kGyroSampleStatusCount = 11;
const char* GyroSampleStatusName(GyroSampleStatus s);
inline std::ostream& operator<<(std::ostream& os, GyroSampleStatus v) { return os << GyroSampleStatusName(v); }
inline bool GyroSampleUsed(GyroSampleStatus s) {
  return s == GyroSampleStatus::kAccepted || s == GyroSampleStatus::kAcceptedPartial ||
         s == GyroSampleStatus::kAcceptedAfterGap || s == GyroSampleStatus::kAcceptedTimeReset;
}

// Why the filter restarted from a star solution (OnlineFusion::last_restart).
enum class RestartReason {
  kNone,       // "none"
  kNonFinite,  // "non_finite": its state was not finite (restored to the last finite one meanwhile)
  kGyroGap,    // "gyro_gap": the gyros did not cover more than policy.max_gyro_gap_s
  kTimeReset,  // "time_reset": the gyro stream's time went back (GyroSampleStatus::kAcceptedTimeReset)
};
const char* RestartReasonName(RestartReason r);
inline std::ostream& operator<<(std::ostream& os, RestartReason v) { return os << RestartReasonName(v); }

class OnlineFusion {
 public:
  // Raw gyro outputs of `unit` (its size, axes and noise figures; the sample interval is
  // 1 / unit.rate_hz). InputError for a bad unit or bad options. The fault monitors' and the bias
  // history's buffers come from `mr` (the heap by default; the flight core's arena, core/arena.h).
  OnlineFusion(const GyroUnit& unit, const FuseOptions& options,
               std::pmr::memory_resource* mr = std::pmr::get_default_resource());

  // One gyro sample: the mean outputs (deg/h) over (t_prev, t_s]. Kept as the latest rate but not
  // propagated before the first attitude measurement (nothing to start from) and when not later than
  // the filter's time. Bad samples are refused or repaired as the status says; the filter goes on.
  GyroSampleStatus AddGyro(double t_s, const GyroVec& g_dph);

  // An attitude measurement (body -> inertial) at t_s with error covariance r_body (rad^2, body axes).
  // The first one initialises the filter. A measurement after the last gyro sample is reached by
  // propagating with the last gyro rate (zero-order hold, the on-board case of a frame arriving before
  // the gyro sample that covers it); one before the current time is refused (returned not accepted),
  // as are the other cases of UpdateStatus.
  MekfUpdate AddAttitude(double t_s, const Quat& q_inertial_from_body, const Mat3& r_body);

  // True from the first measurement on (also while awaiting a restart: q() is then the last finite
  // estimate, and Status() "failed").
  bool initialised() const { return initialised_; }
  // Waiting for a star solution to restart from (restart_pending()), and why it last restarted.
  bool restart_pending() const { return restart_pending_; }
  RestartReason last_restart() const { return last_restart_; }
  long n_restarts() const { return n_restarts_; }
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
  // accepted for policy.failed_after_s (nothing bounds the drift); "failed" before the first measurement
  // and while a restart is pending (restart_pending()); "degraded" while gyro outputs are being
  // dropped (the last sample accepted_partial or rejected: the unit runs without its redundancy) and
  // while the gyros have been silent for more than policy.max_gyro_gap_s (star-only attitude).
  FusionStatus Status() const;
  // The default policies (FusionPolicy in fuse.h holds them and the options may change them).
  static constexpr double kFailedAfterS = FusionPolicy{}.failed_after_s;
  static constexpr double kSettleS = FusionPolicy{}.settle_after_isolation_s;
  std::vector<int> GyrosInUse() const;  // 1-based
  int n_gyros_in_use() const;
  const std::vector<bool>& gyros_in_use_mask() const { return use_; }  // 0-based, allocation-free
  // The body rate of the last usable gyro sample (rad/s, bias not removed; gyros in use, faults compensated).
  const Vec3& last_rate_rad_s() const { return w_last_; }
  // The in-flight calibration of the unit (FuseOptions::calibrate_unit; status "off" without it):
  // refreshed at every star window it closes.
  const UnitCalState& unit_calibration() const { return cal_state_; }
  // Samples of each GyroSampleStatus, and single outputs found unusable (NaN/inf, out of range).
  long n_gyro_status(GyroSampleStatus s) const { return n_status_[static_cast<size_t>(s)]; }
  long n_outputs_non_finite() const { return n_out_nonfinite_; }
  long n_outputs_out_of_range() const { return n_out_range_; }
  long n_bad_measurements() const { return n_bad_meas_; }    // rejected_bad_input
  long n_repeated_measurements() const { return n_repeat_meas_; }
  long n_faults_dropped() const { return n_faults_dropped_; }  // beyond policy.max_fault_events
  long n_gyro_samples() const { return n_gyro_; }
  long n_updates() const { return n_used_; }
  long n_rejected() const { return n_rejected_; }
  long n_late() const { return n_late_; }

 private:
  void PropagateTo(double t_s, const Vec3& w, const GyroVec& g, bool coning);
  // Repairs g's unusable outputs (each replaced by what the other gyros in use predict for it) and
  // says what it found; *partial: a gyro in use was among them.
  GyroSampleStatus CheckOutputs(GyroVec* g, bool* partial);
  // Saves the filter state before a step, and if the step left it non-finite restores it and asks
  // for a restart; true when it had to.
  void SaveFilter();
  bool GuardFilter();
  void RequestRestart(RestartReason why);
  void Restart(double t, const Quat& q, const Mat3& r_body);
  MekfUpdate Update(double t, const Quat& q, const Mat3& r_body);  // AddAttitude past its checks
  void StartEvent(FaultEvent* ev);
  void PushEvent(FaultEvent&& ev);
  void Isolate(int gi, double t, const char* method, const GyroVec& resid, double fault_dph);
  void SetSolver();
  void OnDetection(double t, const char* test, double onset_s, double parity_jump_dph);
  void OpenCovarianceWhileUnresolved();
  void FloorBias(double sigma_rad_s);
  Vec3 BiasAt(double t_s) const;
  // b_before: the bias estimate at the fault's onset (BiasAt), restored when the fault is tracked.
  void Compensate(int gi, double t, const Vec3& b_before);
  void RefitTrackedFault(double t);
  Vec3 RateDph(const GyroVec& g) const { return solver_.Solve(g - correction_ - dyn_); }
  // A sample the calibration takes (every output usable) or that breaks its window.
  void FeedCalibration(double t_s, const GyroVec& g, GyroSampleStatus status);
  void RefreshCalibration();
  MekfUpdate AddAttitudeChecked(double t_s, const Quat& q_inertial_from_body, const Mat3& r_body);

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
  // (t, bias rad/s), one per accepted update: a ring of policy.bias_history_max, n_bias_ from bias_first_.
  ScratchVec<std::pair<double, Vec3>> bias_history_;
  size_t bias_first_ = 0, n_bias_ = 0;
  const std::pair<double, Vec3>& bias_entry(size_t k) const {
    return bias_history_[(bias_first_ + k) % bias_history_.size()];
  }
  std::vector<std::vector<double>> spare_residuals_;  // reserved residual_dph buffers for new events

  // In-flight unit calibration (FuseOptions::calibrate_unit).
  bool cal_on_ = false, cal_applied_ = false;
  InflightCalibrator cal_;
  UnitCalState cal_state_;
  GyroAxes cal_e_;  // N x 3: each gyro's scale factor along its axis and tilts along its normals (E)

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
  // Input checks.
  std::vector<bool> use_scratch_;  // use_ less the unusable outputs of one sample
  bool last_partial_ = false;      // the last gyro sample had an output dropped (or was rejected)
  bool have_jump_ = false;         // a rejected time jump, taken if the next sample confirms it
  double t_jump_ = 0;
  int n_back_ = 0;                 // consecutive out-of-order samples, in order among themselves
  double t_back_ = 0;              // the last of them
  bool have_meas_jump_ = false;    // likewise for a star solution far beyond the filter's time
  double t_meas_jump_ = 0;
  bool restart_pending_ = false;
  RestartReason last_restart_ = RestartReason::kNone;
  long n_restarts_ = 0;
  Quat q_saved_ = Quat::Identity();
  Vec3 bias_saved_ = Vec3::Zero();
  Mat6 p_saved_ = Mat6::Identity();
  std::array<long, kGyroSampleStatusCount> n_status_{};
  long n_out_nonfinite_ = 0, n_out_range_ = 0, n_bad_meas_ = 0, n_repeat_meas_ = 0, n_faults_dropped_ = 0;
};

}  // namespace ssiu
