// Fault detection and isolation for a redundant gyro unit (docs/inertial.md).
// Detection: the parity vector p = V g (V H = 0) holds no body rate, only gyro errors (Potter & Suman
// 1977; Sturza 1988, "Navigation system integrity monitoring using redundant measurements"). Its
// residual e = p - baseline (the baseline is the parity part of the gyros' ordinary biases, tracked
// slowly) feeds two tests: a short-window mean beyond threshold_sigma of its noise (and beyond
// min_jump_dph), quick on large steps; and CUSUM tests (Page 1954; Basseville & Nikiforov 1993,
// "Detection of Abrupt Changes", sec. 2.2), which accumulate evidence sample by sample and so catch
// slow ramps and small steps: for each gyro i in use and each sign, the log-likelihood ratio of a
// fault of +-cusum_fault_dph on gyro i (mean shift d_i = V e_i), and one for a noise burst (the
// parity covariance grown noise_ratio times). The noise covariance C is measured over the warm-up.
// Thresholds from the target false-alarm rate, shared by the n_tests = 2 n_in_use + 1 tests (each
// gets a mean run length to false alarm of n_tests / false_alarm_per_h hours): for the mean tests
// Siegmund's approximation of that run length, (e^b - b - 1) / (delta^2 / 2), b = h + 1.166 delta
// (delta: the design shift in noise sigmas); for the noise test Lorden's bound e^h (Lorden 1971).
// tests/inertial/fdi_test.cc measures the rate on fault-free noise.
// Isolation: with one parity relation (four gyros) every gyro moves p, so parity cannot tell which
// failed; each gyro's output is then compared with the star tracker's rate projected on its axis over
// isolation_window_s, and the gyro whose residual stands out is isolated. With five or more gyros the
// parity direction alone isolates when it matches one gyro's column of V clearly.
#pragma once

#include <limits>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "core/arena.h"
#include "core/json.h"
#include "inertial/gyro_unit.h"

namespace ssiu {

struct FdiOptions {
  double window_s = 10.0;              // parity averaging window
  double threshold_sigma = 6.0;        // detection threshold on the window mean, in its noise sigma
  double min_jump_dph = 1.0;           // and at least this jump (covers bias instability, thermal drift)
  double warmup_s = 30.0;              // parity baseline from this first stretch
  double baseline_tau_s = 900.0;       // then tracked with this time constant while no alarm
  double isolation_window_s = 30.0;    // star-tracker coverage needed to isolate
  double isolation_ratio = 3.0;        // largest residual / second largest
  double isolation_timeout_s = 1800;   // give up isolating after this long ("unresolved")
  double parity_isolation_cos = 0.95;  // 5+ gyros: |cos| between jump and a gyro's parity column
  double false_alarm_per_h = 1e-3;     // target false-alarm rate of the CUSUM tests (per hour of data)
  double cusum_fault_dph = 2.0;        // fault size each mean CUSUM is tuned for (smaller ones take longer)
  double noise_ratio = 4.0;            // parity noise variance growth the noise-burst CUSUM is tuned for
  // The baseline is an estimate (30 s of noise at first): each mean CUSUM's allowance is raised by this
  // many sigmas of the log-likelihood drift its error makes, so that the false-alarm rate holds.
  double baseline_margin_sigma = 3.0;
  double isolation_min_s = 3.0;        // star coverage before a star-rate isolation may be decided
  double isolation_sigma = 5.0;        // and the residual must exceed this many of its noise sigmas
  // A faulty gyro that must stay in use (no spare) is compensated by a step + ramp fitted to its
  // star-rate residual over at most this long a span (so that a fault that changes shape is followed).
  double compensation_window_s = 120.0;

  void Check() const;  // InputError naming the bad field
};

// Where a detected fault stands (JSON spelling: FaultStatusName).
enum class FaultStatus {
  kDetected,    // "detected": awaiting star data to isolate it
  kIsolated,    // "isolated": the gyro is left out (or its fault compensated)
  kUnresolved,  // "unresolved": could not be isolated (still watched)
};
const char* FaultStatusName(FaultStatus s);
inline std::ostream& operator<<(std::ostream& os, FaultStatus v) { return os << FaultStatusName(v); }

struct FaultEvent {
  int gyro = 0;          // 1-based; 0 while not isolated
  double t_onset_s = 0;  // estimated start (the CUSUM's last zero; the detection time otherwise)
  double t_detect_s = 0;
  double t_isolate_s = -1;     // -1 while not isolated
  double parity_jump_dph = 0;  // norm of the parity jump at detection
  FaultStatus status = FaultStatus::kDetected;
  std::string method;                       // "parity" or "star_rates"
  std::string test;                         // what detected it: "window", "cusum", "noise" or "star_innovation"
  std::string shape;                        // "step", "ramp" or "noise" (from the parity since onset)
  double step_dph = 0, ramp_dph_per_s = 0;  // fit since onset, on the isolated gyro (parity units before)
  std::vector<double> residual_dph;         // per-gyro star-rate residuals at isolation (deg/h)
  double fault_dph = 0;                     // estimated fault size on the isolated gyro (deg/h)

  Json ToJson() const;
};

// Short-window parity mean against a tracked baseline.
class ParityMonitor {
 public:
  // The buffers come from `mr` (the heap by default; the flight core's arena, core/arena.h).
  explicit ParityMonitor(std::pmr::memory_resource* mr = std::pmr::get_default_resource())
      : ring_(mr),
        hyp_gyro_(mr),
        hyp_w_(mr),
        hyp_k_(mr),
        hyp_m_(mr),
        hyp_h_(mr),
        s_(mr),
        s_zero_t_(mr),
        hist_(mr),
        short_ring_(mr) {}
  // `use`: gyros in service; `sigma_dph`: per-sample white noise of each gyro (deg/h).
  ParityMonitor(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& sigma_dph, double dt_s,
                const FdiOptions& options, std::pmr::memory_resource* mr = std::pmr::get_default_resource());
  // Starts over as a monitor of `use` (after an isolation), in the buffers it already has: with the
  // same dt_s and options as at construction it allocates nothing.
  void Reset(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& sigma_dph, double dt_s,
             const FdiOptions& options);
  bool active() const { return v_.rows() > 0; }
  // Starts the baseline from gyro-level parity biases (V' p of the monitor this one replaces, after an
  // isolation) instead of the warm-up mean, which a warm-up shorter than the motion's period biases;
  // the warm-up still measures the noise.
  void InheritBaseline(const GyroVec& gyro_parity_bias_dph) {
    inherited_ = gyro_parity_bias_dph;
    has_inherited_ = true;
  }
  // Feeds one sample (deg/h); true when the window mean has jumped away from the baseline.
  bool Feed(double t_s, const GyroVec& g_dph);
  // After an alarm while the fault is unresolved: keeps the residual and its short mean current
  // without testing or moving the baseline.
  void Track(double t_s, const GyroVec& g_dph);
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
  // The CUSUM threshold (log-likelihood units) and the test behind the last alarm ("window", "cusum"
  // or "noise") with its onset estimate (s).
  double cusum_threshold() const { return h_; }
  const std::string& alarm_test() const { return alarm_test_; }
  double onset_s() const { return onset_s_; }
  // Least-squares step + ramp of the parity residual since the onset (deg/h, deg/h per s) and the
  // parity noise variance over it relative to the warm-up's (mean of e' C^-1 e / m).
  void FitSinceOnset(GyroVec* step, GyroVec* ramp_per_s, double* variance_ratio) const;
  // Residual e = p - baseline of the last sample and a short (1 s) mean of it, with the 1-sigma of
  // that mean along each parity axis (from C).
  const GyroVec& short_mean() const { return short_mean_; }
  double short_mean_sigma() const { return short_sigma_; }

 private:
  bool FeedCusum(double t_s, const GyroVec& e);
  void StartCusum(double t_s);
  void UpdateShort(const GyroVec& e);
  FdiOptions opt_;
  GyroParity v_;
  GyroParity cov_window_inv_;  // inverse covariance of a window mean
  int window_n_ = 1;
  double dt_ = 0.01;
  ScratchVec<GyroVec> ring_;
  int ring_pos_ = 0, ring_count_ = 0;
  GyroVec sum_, baseline_, jump_;
  double t_first_ = 0;
  bool started_ = false, ready_ = false;
  GyroVec warm_sum_;
  long warm_n_ = 0;
  // CUSUM state.
  GyroVec warm_mean_;     // running mean and sum of squared deviations of the warm-up parity, for C
  GyroParity warm_m2_;    // (Welford 1962: no store of the samples)
  GyroParity c_inv_;      // inverse noise covariance of one parity sample
  ScratchVec<int> hyp_gyro_;         // gyro of each mean hypothesis
  ScratchVec<GyroVec> hyp_w_;        // f * C^-1 d_i (signed)
  ScratchVec<double> hyp_k_;         // f^2 d_i' C^-1 d_i / 2
  ScratchVec<double> hyp_m_;         // baseline_margin_sigma |f| sqrt(d_i' C^-1 d_i)
  ScratchVec<double> hyp_h_;         // threshold of each
  ScratchVec<double> s_, s_zero_t_;  // statistics and the time each last sat at zero
  double s_noise_ = 0, noise_zero_t_ = 0, h_ = 0;
  // Variance of the baseline's error as a fraction of C: 1 / (warm-up samples), then as the low-pass
  // tracks it (Jones, Champ & Rigdon 2004: a CUSUM on an estimated mean alarms far more often than its
  // known-mean design says).
  double base_var_ = 1;
  std::string alarm_test_;
  GyroVec inherited_;
  bool has_inherited_ = false;
  double onset_s_ = 0;
  ScratchVec<std::pair<double, GyroVec>> hist_;  // (t, e) over the last hist_n_ samples
  int hist_pos_ = 0, hist_n_ = 1;
  ScratchVec<GyroVec> short_ring_;
  int short_pos_ = 0, short_n_ = 1, short_count_ = 0;
  GyroVec short_sum_, short_mean_;
  double short_sigma_ = 0;
};

// One gyro's fault from the star rates: value and slope at t_now with the value's 1-sigma.
struct FaultFit {
  double value_dph = 0;                                        // fault at t_now
  double ramp_dph_per_s = 0;                                   // its slope
  double sigma_dph = std::numeric_limits<double>::infinity();  // 1 sigma of value_dph
  int n = 0;                                                   // star samples the fit used (0: no fit)
};

// Accumulates each gyro's angle (bias-corrected) and the star tracker's body rotation between
// consecutive star samples; residual = gyro angle - axis . star rotation.
class StarRateIsolator {
 public:
  explicit StarRateIsolator(std::pmr::memory_resource* mr = std::pmr::get_default_resource()) : points_(mr) {}
  // Keeps at most max_points star samples (the oldest go first; FitFault then sees less history).
  StarRateIsolator(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& correction_dph,
                   int max_points = kDefaultMaxPoints,
                   std::pmr::memory_resource* mr = std::pmr::get_default_resource());
  static constexpr int kDefaultMaxPoints = 4096;
  // Starts over (a new fault) in the storage it has: allocates nothing when `use` has the size it had.
  void Reset(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& correction_dph);
  // Gyro sample: outputs (deg/h) over dt.
  void AddGyro(const GyroVec& g_dph, double dt_s);
  // Star sample at time t (body -> inertial); intervals since the previous star sample count when the
  // gyros covered them.
  // `r_body`: the sample's error covariance (rad^2, body axes), for the residuals' noise.
  void AddStar(double t_s, const Quat& q_inertial_from_body, const Mat3& r_body = Mat3::Zero());
  // Restarts the star chain (after an outage or rejected sample).
  void BreakChain();
  double covered_s() const { return covered_s_; }
  // Mean residual per gyro (deg/h), 0 for gyros out of service.
  GyroVec ResidualDph() const;
  // Its 1-sigma per gyro from the star noise at the ends of each chain of samples (deg/h).
  GyroVec ResidualSigmaDph() const;
  // Step + ramp of gyro `gi`'s residual (0-based) from the star samples in [t_from_s, t_now_s]: the
  // residual angle accumulated along each chain is fitted, by weighted least squares, as an offset
  // per chain (the star error at its start) plus the integral of a + b (t - t_now); weights from the
  // star covariance along the gyro's axis. sigma_dph is scaled by the fit's chi^2 per degree of
  // freedom when above 1 (a fault that is not a step + ramp over the span). n = 0 with fewer than
  // three samples beyond the chain offsets.
  FaultFit FitFault(int gi, double t_from_s, double t_now_s) const;
  // Drops stored samples before t_s (FitFault never needs them again).
  void ForgetBefore(double t_s);
  int points_stored() const { return n_points_; }
  long points_dropped() const { return n_dropped_; }  // taken out unread because the store was full

 private:
  GyroAxes axes_;
  std::vector<bool> use_;
  GyroVec correction_dph_;
  GyroVec pending_rad_, residual_rad_;
  double pending_s_ = 0;
  bool has_prev_ = false;
  Quat q_prev_ = Quat::Identity();
  double t_prev_ = 0, covered_s_ = 0;
  Mat3 end_cov_ = Mat3::Zero();  // star noise covariance of the chain ends so far
  Mat3 r_prev_ = Mat3::Zero();
  bool chain_open_ = false;
  struct Point {
    double t_s;
    int chain;
    GyroVec angle_rad;  // residual angle accumulated along the chain up to this star sample
    Mat3 r_body;
  };
  const Point& point(int k) const { return points_[(first_point_ + k) % points_.size()]; }
  ScratchVec<Point> points_;  // ring of max_points: n_points_ from first_point_ on
  int first_point_ = 0, n_points_ = 0;
  long n_dropped_ = 0;
  GyroVec chain_angle_rad_;
  int chain_id_ = 0;
};

// The largest body rate error (deg/h) a parity jump of jump_dph can imply if any one gyro in use
// is at fault: |Pinv column i| * jump / |V column i|, maximised over i.
double LargestImpliedRateDph(const GyroParity& v, const RateSolver& solver, const std::vector<bool>& use,
                             double jump_dph);

// Picks the isolated gyro from star residuals (deg/h): the largest |r| if it exceeds min_jump_dph and
// isolation_ratio times the next; -1 otherwise (0-based).
int IsolateFromResiduals(const GyroVec& residual_dph, const std::vector<bool>& use, const FdiOptions& options);
// Sequential form: also needs isolation_min_s of coverage and the largest residual beyond
// isolation_sigma times sigma_dph (the residuals' noise).
int IsolateSequential(const GyroVec& residual_dph, const GyroVec& sigma_dph, double covered_s,
                      const std::vector<bool>& use, const FdiOptions& options);
// CUSUM threshold for n_tests tests on samples at rate_hz and a target false-alarm rate per hour
// (Lorden's bound: any log-likelihood-ratio CUSUM).
double CusumThreshold(int n_tests, double rate_hz, double false_alarm_per_h);
// Threshold giving a mean run length to false alarm of arl_samples for a Gaussian mean-shift CUSUM
// tuned to a shift of delta noise sigmas (Siegmund's approximation).
double CusumThresholdGaussian(double arl_samples, double delta);
// With 2+ parity relations: the gyro whose parity column is parallel to the jump, or -1.
int IsolateFromParity(const GyroParity& v, const GyroVec& jump, const std::vector<bool>& use,
                      const FdiOptions& options);

}  // namespace ssiu
