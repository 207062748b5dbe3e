#include "inertial/fdi.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "inertial/propagate.h"

namespace ssiu {

void FdiOptions::Check() const {
  auto pos = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v)) throw InputError("fdi options", std::string(name) + " must be positive");
  };
  pos(window_s, "window_s");
  pos(threshold_sigma, "threshold_sigma");
  pos(warmup_s, "warmup_s");
  pos(baseline_tau_s, "baseline_tau_s");
  pos(isolation_window_s, "isolation_window_s");
  pos(isolation_timeout_s, "isolation_timeout_s");
  if (!(min_jump_dph >= 0)) throw InputError("fdi options", "min_jump_dph must be >= 0");
  if (!(isolation_ratio >= 1)) throw InputError("fdi options", "isolation_ratio must be >= 1");
  if (!(parity_isolation_cos > 0 && parity_isolation_cos <= 1)) {
    throw InputError("fdi options", "parity_isolation_cos must be in (0, 1]");
  }
}

Json FaultEvent::ToJson() const {
  Json j = {{"gyro", gyro},     {"t_detect_s", t_detect_s}, {"parity_jump_dph", parity_jump_dph},
            {"status", status}, {"method", method},         {"residual_dph", residual_dph},
            {"fault_dph", fault_dph}};
  j["t_isolate_s"] = t_isolate_s >= 0 ? Json(t_isolate_s) : Json(nullptr);
  return j;
}

ParityMonitor::ParityMonitor(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& sigma_dph, double dt_s,
                             const FdiOptions& options)
    : opt_(options), dt_(dt_s) {
  v_ = ParityMatrix(axes, use);
  const int m = static_cast<int>(v_.rows());
  if (m == 0) return;
  window_n_ = std::max(1, static_cast<int>(std::lround(options.window_s / dt_s)));
  GyroParity sigma2 = GyroParity::Zero(axes.rows(), axes.rows());
  for (int i = 0; i < axes.rows(); ++i) sigma2(i, i) = sigma_dph[i] * sigma_dph[i];
  const Eigen::MatrixXd c = Eigen::MatrixXd(v_ * sigma2 * v_.transpose()) / window_n_;
  cov_window_inv_ = c.inverse();
  ring_.assign(window_n_, GyroVec::Zero(m));
  sum_ = GyroVec::Zero(m);
  baseline_ = GyroVec::Zero(m);
  jump_ = GyroVec::Zero(m);
  warm_sum_ = GyroVec::Zero(m);
}

bool ParityMonitor::Feed(double t_s, const GyroVec& g_dph) {
  if (!active()) return false;
  const GyroVec p = v_ * g_dph;
  if (!started_) {
    started_ = true;
    t_first_ = t_s;
  }
  sum_ += p - ring_[ring_pos_];
  ring_[ring_pos_] = p;
  ring_pos_ = (ring_pos_ + 1) % window_n_;
  ring_count_ = std::min(ring_count_ + 1, window_n_);
  if (!ready_) {
    warm_sum_ += p;
    ++warm_n_;
    if (t_s - t_first_ >= opt_.warmup_s && ring_count_ == window_n_) {
      baseline_ = warm_sum_ / static_cast<double>(warm_n_);
      ready_ = true;
    }
    return false;
  }
  const GyroVec mean = sum_ / static_cast<double>(window_n_);
  jump_ = mean - baseline_;
  const double stat = std::sqrt(jump_.dot(cov_window_inv_ * jump_));
  if (stat > opt_.threshold_sigma && jump_.norm() > opt_.min_jump_dph) return true;
  // Track slow drift of the gyros' biases (first-order low-pass of the parity).
  baseline_ += (p - baseline_) * (dt_ / opt_.baseline_tau_s);
  return false;
}

GyroVec ParityMonitor::StepEstimate(double* age_s) const {
  GyroVec best = jump_, acc = GyroVec::Zero(baseline_.size());
  double best_score = -1;
  int best_k = ring_count_;
  for (int k = 1; k <= ring_count_; ++k) {
    acc += ring_[(ring_pos_ - k + 2 * window_n_) % window_n_] - baseline_;
    const double score = acc.squaredNorm() / k;
    if (score > best_score) {
      best_score = score;
      best = acc / static_cast<double>(k);
      best_k = k;
    }
  }
  if (age_s) *age_s = best_k * dt_;
  return best;
}

StarRateIsolator::StarRateIsolator(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& correction_dph)
    : axes_(axes), use_(use), correction_dph_(correction_dph) {
  pending_rad_ = GyroVec::Zero(axes.rows());
  residual_rad_ = GyroVec::Zero(axes.rows());
}

void StarRateIsolator::AddGyro(const GyroVec& g_dph, double dt_s) {
  const double k = kDegToRad / 3600.0;
  pending_rad_ += (g_dph - correction_dph_) * (k * dt_s);
  pending_s_ += dt_s;
}

void StarRateIsolator::AddStar(double t_s, const Quat& q) {
  if (has_prev_ && pending_s_ > 0 && std::abs(pending_s_ - (t_s - t_prev_)) < 1e-6 * std::max(1.0, t_s)) {
    // Body rotation between the two star samples, in body axes at the first one.
    const Vec3 rot = RotationVectorFromQuat(q_prev_.conjugate() * q);
    residual_rad_ += pending_rad_ - axes_ * rot;
    covered_s_ += t_s - t_prev_;
  }
  has_prev_ = true;
  q_prev_ = q;
  t_prev_ = t_s;
  pending_rad_.setZero();
  pending_s_ = 0;
}

void StarRateIsolator::BreakChain() {
  has_prev_ = false;
  pending_rad_.setZero();
  pending_s_ = 0;
}

GyroVec StarRateIsolator::ResidualDph() const {
  GyroVec r = GyroVec::Zero(residual_rad_.size());
  if (covered_s_ <= 0) return r;
  for (int i = 0; i < r.size(); ++i) {
    if (use_[i]) r[i] = residual_rad_[i] / covered_s_ * kRadToDeg * 3600.0;
  }
  return r;
}

double LargestImpliedRateDph(const GyroParity& v, const RateSolver& solver, const std::vector<bool>& use, double jump_dph) {
  double worst = 0;
  for (int i = 0; i < static_cast<int>(v.cols()); ++i) {
    const double vi = v.col(i).norm();
    if (use[i] && vi > 1e-9) worst = std::max(worst, solver.Pinv().col(i).norm() * jump_dph / vi);
  }
  return worst;
}

int IsolateFromResiduals(const GyroVec& r, const std::vector<bool>& use, const FdiOptions& options) {
  int best = -1;
  double a1 = 0, a2 = 0;
  for (int i = 0; i < r.size(); ++i) {
    if (!use[i]) continue;
    const double a = std::abs(r[i]);
    if (a > a1) {
      a2 = a1;
      a1 = a;
      best = i;
    } else if (a > a2) {
      a2 = a;
    }
  }
  if (best < 0 || a1 < options.min_jump_dph || a1 < options.isolation_ratio * a2) return -1;
  return best;
}

int IsolateFromParity(const GyroParity& v, const GyroVec& jump, const std::vector<bool>& use, const FdiOptions& options) {
  if (v.rows() < 2 || jump.norm() == 0) return -1;
  int best = -1, count = 0;
  for (int i = 0; i < v.cols(); ++i) {
    if (!use[i]) continue;
    const double n = v.col(i).norm();
    if (n < 1e-9) continue;
    const double c = std::abs(v.col(i).dot(jump)) / (n * jump.norm());
    if (c >= options.parity_isolation_cos) {
      best = i;
      ++count;
    }
  }
  return count == 1 ? best : -1;
}

}  // namespace ssiu
