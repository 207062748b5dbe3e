// Fault detection and isolation for a redundant gyro unit (docs/inertial.md).
// Detection: the parity vector p = V g (V H = 0) holds no body rate, only gyro errors; its short-window
// mean is compared with a slowly tracked baseline (the parity part of the gyros' ordinary biases), a
// jump beyond threshold_sigma of its noise (and beyond min_jump_dph) is a fault (Potter & Suman 1977;
// Sturza 1988, "Navigation system integrity monitoring using redundant measurements").
// Isolation: with one parity relation (four gyros) every gyro moves p, so parity cannot tell which
// failed; each gyro's output is then compared with the star tracker's rate projected on its axis over
// isolation_window_s, and the gyro whose residual stands out is isolated. With five or more gyros the
// parity direction alone isolates when it matches one gyro's column of V clearly.
#pragma once

#include <string>
#include <vector>

#include "core/json.h"
#include "inertial/gyro_unit.h"

namespace ssiu {

struct FdiOptions {
  double window_s = 10.0;            // parity averaging window
  double threshold_sigma = 6.0;      // detection threshold on the window mean, in its noise sigma
  double min_jump_dph = 1.0;         // and at least this jump (covers bias instability, thermal drift)
  double warmup_s = 30.0;            // parity baseline from this first stretch
  double baseline_tau_s = 900.0;     // then tracked with this time constant while no alarm
  double isolation_window_s = 30.0;  // star-tracker coverage needed to isolate
  double isolation_ratio = 3.0;      // largest residual / second largest
  double isolation_timeout_s = 1800; // give up isolating after this long ("unresolved")
  double parity_isolation_cos = 0.95;  // 5+ gyros: |cos| between jump and a gyro's parity column

  void Check() const;  // InputError naming the bad field
};

struct FaultEvent {
  int gyro = 0;                  // 1-based; 0 while not isolated
  double t_detect_s = 0;
  double t_isolate_s = -1;       // -1 while not isolated
  double parity_jump_dph = 0;    // norm of the parity jump at detection
  std::string status;            // "isolated", "detected" (awaiting star data), "unresolved"
  std::string method;            // "parity" or "star_rates"
  std::vector<double> residual_dph;  // per-gyro star-rate residuals at isolation (deg/h)
  double fault_dph = 0;          // estimated fault size on the isolated gyro (deg/h)

  Json ToJson() const;
};

// Short-window parity mean against a tracked baseline.
class ParityMonitor {
 public:
  ParityMonitor() = default;
  // `use`: gyros in service; `sigma_dph`: per-sample white noise of each gyro (deg/h).
  ParityMonitor(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& sigma_dph, double dt_s,
                const FdiOptions& options);
  bool active() const { return v_.rows() > 0; }
  // Feeds one sample (deg/h); true when the window mean has jumped away from the baseline.
  bool Feed(double t_s, const GyroVec& g_dph);
  const GyroParity& V() const { return v_; }
  // Baseline parity (deg/h) and the latest window mean minus it.
  const GyroVec& baseline() const { return baseline_; }
  const GyroVec& jump() const { return jump_; }
  // At an alarm the window mean understates a step that began inside the window. The step as a
  // change-point fit over the window: the onset maximising |sum since onset - baseline|^2 / count
  // (the likelihood ratio of a mean shift in white noise, Basseville & Nikiforov 1993, sec. 2.2),
  // returning the mean parity since that onset minus the baseline and the onset's age (s).
  GyroVec StepEstimate(double* age_s) const;
  bool ready() const { return ready_; }

 private:
  FdiOptions opt_;
  GyroParity v_;
  Eigen::MatrixXd cov_window_inv_;  // inverse covariance of a window mean
  int window_n_ = 1;
  double dt_ = 0.01;
  std::vector<GyroVec> ring_;
  int ring_pos_ = 0, ring_count_ = 0;
  GyroVec sum_, baseline_, jump_;
  double t_first_ = 0;
  bool started_ = false, ready_ = false;
  GyroVec warm_sum_;
  long warm_n_ = 0;
};

// Accumulates each gyro's angle (bias-corrected) and the star tracker's body rotation between
// consecutive star samples; residual = gyro angle - axis . star rotation.
class StarRateIsolator {
 public:
  StarRateIsolator() = default;
  StarRateIsolator(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& correction_dph);
  // Gyro sample: outputs (deg/h) over dt.
  void AddGyro(const GyroVec& g_dph, double dt_s);
  // Star sample at time t (body -> inertial); intervals since the previous star sample count when the
  // gyros covered them.
  void AddStar(double t_s, const Quat& q_inertial_from_body);
  // Restarts the star chain (after an outage or rejected sample).
  void BreakChain();
  double covered_s() const { return covered_s_; }
  // Mean residual per gyro (deg/h), 0 for gyros out of service.
  GyroVec ResidualDph() const;

 private:
  GyroAxes axes_;
  std::vector<bool> use_;
  GyroVec correction_dph_;
  GyroVec pending_rad_, residual_rad_;
  double pending_s_ = 0;
  bool has_prev_ = false;
  Quat q_prev_ = Quat::Identity();
  double t_prev_ = 0, covered_s_ = 0;
};

// The largest body rate error (deg/h) a parity jump of jump_dph can imply if any one gyro in use
// is at fault: |Pinv column i| * jump / |V column i|, maximised over i.
double LargestImpliedRateDph(const GyroParity& v, const RateSolver& solver, const std::vector<bool>& use, double jump_dph);

// Picks the isolated gyro from star residuals (deg/h): the largest |r| if it exceeds min_jump_dph and
// isolation_ratio times the next; -1 otherwise (0-based).
int IsolateFromResiduals(const GyroVec& residual_dph, const std::vector<bool>& use, const FdiOptions& options);
// With 2+ parity relations: the gyro whose parity column is parallel to the jump, or -1.
int IsolateFromParity(const GyroParity& v, const GyroVec& jump, const std::vector<bool>& use,
                      const FdiOptions& options);

}  // namespace ssiu
