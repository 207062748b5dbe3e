#include "inertial/online_fusion.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"

namespace ssiu {
namespace {

constexpr double kDphToRadS = kDegToRad / 3600.0;
constexpr double kRadSToDph = 1.0 / kDphToRadS;

}  // namespace

OnlineFusion::OnlineFusion(const GyroUnit& unit, const FuseOptions& options) : unit_(unit), opt_(options) {
  opt_.Check();
  unit_.Check("unit");
  const int n = unit_.size();
  axes_ = unit_.Axes();
  arw_ = unit_.NoiseArw();
  use_.assign(n, true);
  correction_ = GyroVec::Zero(n);
  g_last_ = GyroVec::Zero(n);
  SetSolver();
  dt_nominal_ = 1.0 / unit_.rate_hz;
  sample_sigma_dph_ = arw_ * (60.0 / std::sqrt(dt_nominal_));  // deg/sqrt(h) -> deg/h per sample
  fdi_on_ = opt_.fdi && n >= 4;
  if (fdi_on_) monitor_ = ParityMonitor(axes_, use_, sample_sigma_dph_, dt_nominal_, opt_.fdi_options);
}

void OnlineFusion::SetSolver() {
  solver_ = RateSolver(axes_, arw_, use_);
  noise_ = FuseNoiseModel(unit_, solver_, opt_.bias_drift_floor_dph_per_sqrt_h);
}

std::vector<int> OnlineFusion::GyrosInUse() const {
  std::vector<int> out;
  for (size_t i = 0; i < use_.size(); ++i) {
    if (use_[i]) out.push_back(static_cast<int>(i) + 1);
  }
  return out;
}

void OnlineFusion::PropagateTo(double t_s, const Vec3& w, const GyroVec& g, bool coning) {
  const double d = t_s - t_cur_;
  filter_.Propagate(w, d, noise_, coning);
  if (isolating_) isolator_.AddGyro(g, d);
  t_cur_ = t_s;
}

// As Fuse(): the isolated gyro leaves the rate solution, the parity baseline becomes a per-gyro
// correction, and the bias estimate drops what the fault leaked into it (its covariance opens by as much).
void OnlineFusion::Isolate(int gi, double t, const char* method, const GyroVec& resid, double fault_dph) {
  const int n = unit_.size();
  FaultEvent& ev = faults_.back();
  ev.gyro = gi + 1;
  ev.t_isolate_s = t;
  ev.status = "isolated";
  ev.method = method;
  ev.fault_dph = fault_dph;
  ev.residual_dph.assign(resid.data(), resid.data() + resid.size());
  correction_ = GyroVec::Zero(n);
  if (monitor_.active() && monitor_.ready()) correction_ = monitor_.V().transpose() * monitor_.baseline();
  const Vec3 leak_rad_s = solver_.Pinv().col(gi) * fault_dph * kDphToRadS;
  const double leak = leak_rad_s.norm();
  filter_.ShiftBias(-leak_rad_s);
  use_[gi] = false;
  SetSolver();
  monitor_ = ParityMonitor(axes_, use_, sample_sigma_dph_, dt_nominal_, opt_.fdi_options);
  filter_.InflateBias(leak);
  isolating_ = false;
}

void OnlineFusion::AddGyro(double t_k, const GyroVec& g) {
  const int n = unit_.size();
  if (g.size() != n) {
    throw InputError("gyro sample", "has " + std::to_string(g.size()) + " outputs but the unit has " + std::to_string(n));
  }
  const double t_prev = have_gyro_ ? t_last_gyro_ : t_k - dt_nominal_;
  have_gyro_ = true;
  t_last_gyro_ = t_k;
  g_last_ = g;
  // The rate for this step comes from the gyros in use before any isolation at this sample (as Fuse()).
  const Vec3 w = solver_.Solve(g - correction_) * kDphToRadS;
  w_last_ = w;
  if (!initialised_ || t_k <= t_cur_) return;
  const double full = t_k - t_prev;
  ++n_gyro_;

  if (fdi_on_ && !isolating_ && monitor_.Feed(t_k, g)) {
    FaultEvent ev;
    ev.t_detect_s = t_k;
    ev.parity_jump_dph = monitor_.jump().norm();
    ev.status = "detected";
    faults_.push_back(ev);
    // The size of the step, not the window mean that crossed the threshold.
    const GyroVec step = monitor_.StepEstimate(nullptr);
    const double worst_dph = LargestImpliedRateDph(monitor_.V(), solver_, use_, step.norm());
    // The fault began at most one parity window ago and has turned the attitude since, unknown to
    // the filter: open the attitude covariance by that angle, or the NIS gate refuses the very
    // star fixes that would correct it.
    filter_.InflateAttitude(worst_dph * kDphToRadS * opt_.fdi_options.window_s);
    const int gi = IsolateFromParity(monitor_.V(), monitor_.jump(), use_, opt_.fdi_options);
    if (gi >= 0) {
      const double f = step.dot(monitor_.V().col(gi)) / monitor_.V().col(gi).squaredNorm();
      Isolate(gi, t_k, "parity", GyroVec::Zero(n), f);
      w_last_ = solver_.Solve(g - correction_) * kDphToRadS;
    } else {
      // Gyro-level biases before the fault: body bias from before the window plus the parity part.
      const Vec3 b_before = bias_history_.empty() ? filter_.bias() : bias_history_.front().second;
      const GyroVec c = axes_ * (b_before * kRadSToDph) + monitor_.V().transpose() * monitor_.baseline();
      isolator_ = StarRateIsolator(axes_, use_, c);
      isolating_ = true;
      // Until isolation the fault feeds the bias: open its covariance by the largest body bias the
      // parity jump can imply, so that the filter follows instead of diverging.
      filter_.InflateBias(worst_dph * kDphToRadS);
    }
  }
  const double d = t_k - t_cur_;
  PropagateTo(t_k, w, g, std::abs(d - full) < 1e-9 * full);
}

MekfUpdate OnlineFusion::AddAttitude(double t_j, const Quat& q_meas, const Mat3& r_body) {
  MekfUpdate u;
  if (!initialised_) {
    Mat6 p0 = Mat6::Zero();
    p0.block<3, 3>(0, 0) = r_body;
    const double b0 = opt_.init_bias_sigma_dph * kDphToRadS;
    p0.block<3, 3>(3, 3) = Mat3::Identity() * b0 * b0;
    filter_.Init(q_meas, Vec3::Zero(), p0);
    initialised_ = true;
    t_cur_ = t_last_st_ = t_j;
    n_used_ = 1;
    u.accepted = true;
    return u;
  }
  if (t_j < t_cur_ - 1e-9) {
    ++n_late_;
    return u;
  }
  if (t_j > t_cur_) PropagateTo(t_j, w_last_, g_last_, false);

  const double gap = t_j - t_last_st_;
  t_last_st_ = t_j;
  // Star rates for isolation do not depend on the filter: every measurement counts.
  if (isolating_) {
    if (gap > 5.0) isolator_.BreakChain();
    isolator_.AddStar(t_j, q_meas);
  }
  // A run of rejections means the filter, not the star tracker, is wrong: accept the next one.
  const double gate = consecutive_rejects_ >= 5 ? std::numeric_limits<double>::infinity() : opt_.nis_gate;
  u = filter_.UpdateAttitude(q_meas, r_body, gate);
  if (!u.accepted) {
    ++n_rejected_;
    ++consecutive_rejects_;
  } else {
    consecutive_rejects_ = 0;
    ++n_used_;
    bias_history_.emplace_back(t_j, filter_.bias());
    while (bias_history_.size() > 2 && bias_history_.front().first < t_j - 3 * opt_.fdi_options.window_s) {
      bias_history_.pop_front();
    }
  }
  if (!isolating_) return u;
  FaultEvent& ev = faults_.back();
  if (isolator_.covered_s() >= opt_.fdi_options.isolation_window_s) {
    const GyroVec r = isolator_.ResidualDph();
    const int gi = IsolateFromResiduals(r, use_, opt_.fdi_options);
    if (gi >= 0) {
      Isolate(gi, t_j, "star_rates", r, r[gi]);
      w_last_ = solver_.Solve(g_last_ - correction_) * kDphToRadS;
    } else if (t_j - ev.t_detect_s > opt_.fdi_options.isolation_timeout_s) {
      ev.status = "unresolved";
      ev.residual_dph.assign(r.data(), r.data() + r.size());
      isolating_ = false;
    }
  }
  return u;
}

}  // namespace ssiu
