#include "inertial/fdi.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

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
  pos(false_alarm_per_h, "false_alarm_per_h");
  pos(cusum_fault_dph, "cusum_fault_dph");
  pos(isolation_min_s, "isolation_min_s");
  pos(isolation_sigma, "isolation_sigma");
  pos(compensation_window_s, "compensation_window_s");
  if (!(baseline_margin_sigma >= 0) || !std::isfinite(baseline_margin_sigma)) {
    throw InputError("fdi options", "baseline_margin_sigma must be >= 0");
  }
  if (!(noise_ratio > 1) || !std::isfinite(noise_ratio)) throw InputError("fdi options", "noise_ratio must be > 1");
}

double CusumThreshold(int n_tests, double rate_hz, double false_alarm_per_h) {
  // Lorden's bound: each test's mean run length to a false alarm is >= e^h samples; n_tests of them
  // together alarm falsely at most n_tests e^-h times per sample.
  return std::log(std::max(1, n_tests) * rate_hz * 3600.0 / false_alarm_per_h);
}

double CusumThresholdGaussian(double arl_samples, double delta) {
  // Siegmund's corrected approximation for a Gaussian mean-shift CUSUM on the log-likelihood ratio
  // (increments delta z - delta^2 / 2): ARL0 = (e^b - b - 1) / (delta^2 / 2), b = h + 1.166 delta
  // (Siegmund 1985, "Sequential Analysis", eq. 2.56; Basseville & Nikiforov eq. 5.2.44). Lorden's
  // e^h is the small-delta-loose bound of it.
  const double target = arl_samples * delta * delta / 2;
  if (!(target > 1)) return 0;
  double b = std::log(target) + 1;
  for (int it = 0; it < 50; ++it) b -= (std::exp(b) - b - 1 - target) / (std::exp(b) - 1);  // Newton
  return std::max(0.0, b - 1.166 * delta);
}

const char* FaultStatusName(FaultStatus s) {
  switch (s) {
    case FaultStatus::kDetected:
      return "detected";
    case FaultStatus::kIsolated:
      return "isolated";
    case FaultStatus::kUnresolved:
      return "unresolved";
  }
  return "unresolved";
}

Json FaultEvent::ToJson() const {
  Json j = {{"gyro", gyro},
            {"t_detect_s", t_detect_s},
            {"parity_jump_dph", parity_jump_dph},
            {"status", FaultStatusName(status)},
            {"method", method},
            {"residual_dph", residual_dph},
            {"fault_dph", fault_dph}};
  j["t_isolate_s"] = t_isolate_s >= 0 ? Json(t_isolate_s) : Json(nullptr);
  j["t_onset_s"] = t_onset_s;
  j["test"] = test;
  j["shape"] = shape;
  j["step_dph"] = step_dph;
  j["ramp_dph_per_s"] = ramp_dph_per_s;
  return j;
}

ParityMonitor::ParityMonitor(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& sigma_dph, double dt_s,
                             const FdiOptions& options, std::pmr::memory_resource* mr)
    : ParityMonitor(mr) {
  Reset(axes, use, sigma_dph, dt_s, options);
}

void ParityMonitor::Reset(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& sigma_dph, double dt_s,
                          const FdiOptions& options) {
  // Every member back to its initial value, the buffers kept (their capacity is the point: after the
  // first construction a reset on the per-sample path allocates nothing).
  // (A move keeps a buffer's memory resource, and so does the assignment of a fresh monitor.)
  ScratchVec<GyroVec> ring = std::move(ring_), short_ring = std::move(short_ring_);
  ScratchVec<std::pair<double, GyroVec>> hist = std::move(hist_);
  ScratchVec<int> hyp_gyro = std::move(hyp_gyro_);
  ScratchVec<GyroVec> hyp_w = std::move(hyp_w_);
  ScratchVec<double> hyp_k = std::move(hyp_k_), hyp_m = std::move(hyp_m_), hyp_h = std::move(hyp_h_), s = std::move(s_),
                     s_zero_t = std::move(s_zero_t_);
  *this = ParityMonitor();
  ring_ = std::move(ring);
  short_ring_ = std::move(short_ring);
  hist_ = std::move(hist);
  hyp_gyro_ = std::move(hyp_gyro);
  hyp_w_ = std::move(hyp_w);
  hyp_k_ = std::move(hyp_k);
  hyp_m_ = std::move(hyp_m);
  hyp_h_ = std::move(hyp_h);
  s_ = std::move(s);
  s_zero_t_ = std::move(s_zero_t);
  ring_.clear();
  short_ring_.clear();
  hist_.clear();
  hyp_gyro_.clear();
  hyp_w_.clear();
  hyp_k_.clear();
  hyp_m_.clear();
  hyp_h_.clear();
  s_.clear();
  s_zero_t_.clear();
  opt_ = options;
  dt_ = dt_s;
  v_ = ParityMatrix(axes, use);
  const int m = static_cast<int>(v_.rows());
  if (m == 0) return;
  window_n_ = std::max(1, static_cast<int>(std::lround(options.window_s / dt_s)));
  GyroParity sigma2 = GyroParity::Zero(axes.rows(), axes.rows());
  for (int i = 0; i < axes.rows(); ++i) sigma2(i, i) = sigma_dph[i] * sigma_dph[i];
  const GyroParity c = GyroParity(v_ * sigma2 * v_.transpose()) / window_n_;
  cov_window_inv_ = c.inverse();
  ring_.assign(window_n_, GyroVec::Zero(m));
  sum_ = GyroVec::Zero(m);
  baseline_ = GyroVec::Zero(m);
  jump_ = GyroVec::Zero(m);
  warm_sum_ = GyroVec::Zero(m);
  warm_mean_ = GyroVec::Zero(m);
  warm_m2_ = GyroParity::Zero(m, m);
  hist_n_ = std::max(1, static_cast<int>(std::lround(120.0 / dt_s)));
  hist_.reserve(hist_n_);  // filled when the warm-up ends
  short_n_ = std::max(1, static_cast<int>(std::lround(1.0 / dt_s)));
  short_ring_.assign(short_n_, GyroVec::Zero(m));
  short_sum_ = GyroVec::Zero(m);
  short_mean_ = GyroVec::Zero(m);
  hyp_gyro_.reserve(kMaxGyros);
  for (int i = 0; i < axes.rows(); ++i) {
    if (use[i]) hyp_gyro_.push_back(i);
  }
  for (auto* v : {&hyp_k_, &hyp_m_, &hyp_h_, &s_, &s_zero_t_}) v->reserve(2 * kMaxGyros);
  hyp_w_.reserve(2 * kMaxGyros);
  const int n_tests = 2 * static_cast<int>(hyp_gyro_.size()) + 1;
  h_ = CusumThreshold(n_tests, 1.0 / dt_s, options.false_alarm_per_h);
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
    const GyroVec d = p - warm_mean_;
    warm_mean_ += d / static_cast<double>(warm_n_);
    warm_m2_ += d * (p - warm_mean_).transpose();
    if (t_s - t_first_ >= opt_.warmup_s && ring_count_ == window_n_) {
      baseline_ = warm_sum_ / static_cast<double>(warm_n_);
      StartCusum(t_s);
      ready_ = true;
    }
    return false;
  }
  const GyroVec e = p - baseline_;
  UpdateShort(e);
  const GyroVec mean = sum_ / static_cast<double>(window_n_);
  jump_ = mean - baseline_;
  const double stat = std::sqrt(jump_.dot(cov_window_inv_ * jump_));
  const bool cusum = FeedCusum(t_s, e);
  if (stat > opt_.threshold_sigma && jump_.norm() > opt_.min_jump_dph) {
    if (!cusum) {  // the window test alone: the onset lies within the window
      alarm_test_ = "window";
      double age = 0;
      StepEstimate(&age);
      onset_s_ = t_s - age;
    }
    return true;
  }
  if (cusum) return true;
  // Track slow drift of the gyros' biases (first-order low-pass of the parity).
  const double a = dt_ / opt_.baseline_tau_s;
  baseline_ += (p - baseline_) * a;
  base_var_ = (1 - a) * (1 - a) * base_var_ + a * a;
  return false;
}

void ParityMonitor::Track(double t_s, const GyroVec& g_dph) {
  if (!active() || !ready_) return;
  const GyroVec e = v_ * g_dph - baseline_;
  UpdateShort(e);
  hist_[hist_pos_] = {t_s, e};
  hist_pos_ = (hist_pos_ + 1) % hist_n_;
}

void ParityMonitor::UpdateShort(const GyroVec& e) {
  short_sum_ += e - short_ring_[short_pos_];
  short_ring_[short_pos_] = e;
  short_pos_ = (short_pos_ + 1) % short_n_;
  short_count_ = std::min(short_count_ + 1, short_n_);
  short_mean_ = short_sum_ / static_cast<double>(short_count_);
}

void ParityMonitor::StartCusum(double t_s) {
  const int m = static_cast<int>(v_.rows());
  // The warm-up covariance about its mean (= baseline_ here).
  GyroParity c = (warm_m2_ + warm_m2_.transpose()) / (2.0 * static_cast<double>(std::max<long>(2, warm_n_) - 1));
  // Never below a tenth of the modelled noise: a quantised or silent log must not make C singular.
  const GyroParity c_model = GyroParity(cov_window_inv_.inverse()) * window_n_;
  for (int i = 0; i < m; ++i) c(i, i) = std::max(c(i, i), 0.1 * c_model(i, i));
  if (has_inherited_) baseline_ = v_ * inherited_;
  // The warm-up mean's error (an inherited baseline is taken as no better than one).
  base_var_ = 1.0 / static_cast<double>(std::max<long>(1, warm_n_));
  c_inv_ = c.inverse();
  short_sigma_ = std::sqrt(c.diagonal().maxCoeff() / short_n_);
  const int n_tests = 2 * static_cast<int>(hyp_gyro_.size()) + 1;
  const double arl = n_tests * 3600.0 / dt_ / opt_.false_alarm_per_h;  // per test, in samples
  for (int i : hyp_gyro_) {
    const GyroVec d = v_.col(i);
    const double dd = d.dot(c_inv_ * d);
    if (!(dd > 1e-12)) continue;  // a gyro outside every parity relation cannot be watched
    for (double sign : {1.0, -1.0}) {
      const double f = sign * opt_.cusum_fault_dph;
      hyp_w_.push_back(f * (c_inv_ * d));
      hyp_k_.push_back(0.5 * f * f * dd);
      hyp_m_.push_back(opt_.baseline_margin_sigma * std::abs(f) * std::sqrt(dd));
      hyp_h_.push_back(CusumThresholdGaussian(arl, opt_.cusum_fault_dph * std::sqrt(dd)));
    }
  }
  s_.assign(hyp_w_.size(), 0.0);
  s_zero_t_.assign(hyp_w_.size(), t_s);
  s_noise_ = 0;
  noise_zero_t_ = t_s;
  hist_.assign(hist_n_, {t_s, GyroVec::Zero(m)});
}

bool ParityMonitor::FeedCusum(double t_s, const GyroVec& e) {
  hist_[hist_pos_] = {t_s, e};
  hist_pos_ = (hist_pos_ + 1) % hist_n_;
  // Page's recursion S = max(0, S + llr) on each log-likelihood ratio (Basseville & Nikiforov eq. 2.2.11).
  // The residual is taken from an estimated baseline whose error eps ~ N(0, base_var_ C) biases every
  // increment by w_j' eps (1 sigma |f| sqrt(d' C^-1 d base_var_)): the thresholds assume a known mean,
  // and a baseline 2-3 sigma off multiplies the false-alarm rate by 10^2-10^4, so the allowance covers
  // baseline_margin_sigma of it (at 30 s about 0.5-0.8 of the allowance, a tenth after the baseline has
  // tracked for 2 tau).
  const double base_sigma = std::sqrt(base_var_);
  int fired = -1;
  for (size_t j = 0; j < s_.size(); ++j) {
    s_[j] = std::max(0.0, s_[j] + hyp_w_[j].dot(e) - hyp_k_[j] - hyp_m_[j] * base_sigma);
    if (s_[j] == 0) s_zero_t_[j] = t_s;
    if (s_[j] > hyp_h_[j] && (fired < 0 || s_[j] - hyp_h_[j] > s_[fired] - hyp_h_[fired])) fired = static_cast<int>(j);
  }
  // Noise burst: C -> rho C, llr = (1 - 1/rho) e'C^-1 e / 2 - m ln(rho) / 2.
  const double rho = opt_.noise_ratio, m = static_cast<double>(e.size());
  s_noise_ = std::max(0.0, s_noise_ + 0.5 * (1 - 1 / rho) * e.dot(c_inv_ * e) - 0.5 * m * std::log(rho));
  if (s_noise_ == 0) noise_zero_t_ = t_s;
  if (fired >= 0) {
    alarm_test_ = "cusum";
    onset_s_ = s_zero_t_[fired];
    return true;
  }
  if (s_noise_ > h_) {
    alarm_test_ = "noise";
    onset_s_ = noise_zero_t_;
    return true;
  }
  return false;
}

void ParityMonitor::FitSinceOnset(GyroVec* step, GyroVec* ramp_per_s, double* variance_ratio) const {
  const int m = static_cast<int>(baseline_.size());
  // Least squares e = a + b (t - onset) over the stored samples since the onset.
  double s0 = 0, s1 = 0, s2 = 0;
  GyroVec sy = GyroVec::Zero(m), sty = GyroVec::Zero(m);
  for (const auto& [t, e] : hist_) {
    if (t < onset_s_ - 1e-9 || !std::isfinite(t)) continue;
    const double x = t - onset_s_;
    s0 += 1;
    s1 += x;
    s2 += x * x;
    sy += e;
    sty += x * e;
  }
  const double det = s0 * s2 - s1 * s1;
  GyroVec a = s0 > 0 ? GyroVec(sy / s0) : GyroVec::Zero(m), b = GyroVec::Zero(m);
  if (s0 >= 3 && det > 1e-12 * s0 * s2) {
    a = (s2 * sy - s1 * sty) / det;
    b = (s0 * sty - s1 * sy) / det;
  }
  double q = 0;
  for (const auto& [t, e] : hist_) {
    if (t < onset_s_ - 1e-9) continue;
    const GyroVec r = e - a - b * (t - onset_s_);
    q += r.dot(c_inv_ * r);
  }
  if (step) *step = a;
  if (ramp_per_s) *ramp_per_s = b;
  if (variance_ratio) *variance_ratio = s0 > 3 ? q / ((s0 - 2) * m) : 1.0;
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

StarRateIsolator::StarRateIsolator(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& correction_dph,
                                   int max_points, std::pmr::memory_resource* mr)
    : StarRateIsolator(mr) {
  points_.resize(static_cast<size_t>(std::max(1, max_points)));
  Reset(axes, use, correction_dph);
}

void StarRateIsolator::Reset(const GyroAxes& axes, const std::vector<bool>& use, const GyroVec& correction_dph) {
  ScratchVec<Point> points = std::move(points_);
  std::vector<bool> use_kept = std::move(use_);
  *this = StarRateIsolator();
  points_ = std::move(points);
  use_ = std::move(use_kept);
  use_ = use;  // same size: no allocation
  axes_ = axes;
  correction_dph_ = correction_dph;
  pending_rad_ = GyroVec::Zero(axes.rows());
  residual_rad_ = GyroVec::Zero(axes.rows());
  chain_angle_rad_ = GyroVec::Zero(axes.rows());
}

void StarRateIsolator::AddGyro(const GyroVec& g_dph, double dt_s) {
  pending_rad_ += (g_dph - correction_dph_) * (kDphToRadS * dt_s);
  pending_s_ += dt_s;
}

void StarRateIsolator::AddStar(double t_s, const Quat& q, const Mat3& r_body) {
  if (has_prev_ && pending_s_ > 0 && std::abs(pending_s_ - (t_s - t_prev_)) < 1e-6 * std::max(1.0, t_s)) {
    // Body rotation between the two star samples, in body axes at the first one.
    const Vec3 rot = RotationVectorFromQuat(q_prev_.conjugate() * q);
    const GyroVec d = pending_rad_ - axes_ * rot;
    residual_rad_ += d;
    chain_angle_rad_ += d;
    covered_s_ += t_s - t_prev_;
    // Along a chain the star noise of the inner samples cancels (to first order): only its two
    // ends count.
    if (!chain_open_) end_cov_ += r_prev_;
    chain_open_ = true;
  } else {
    if (chain_open_) end_cov_ += r_prev_;
    chain_open_ = false;
    ++chain_id_;
    chain_angle_rad_.setZero();
  }
  // A full store drops its oldest sample (a fit then covers less than compensation_window_s).
  if (points_.empty()) points_.resize(kDefaultMaxPoints);
  if (n_points_ == static_cast<int>(points_.size())) {
    first_point_ = (first_point_ + 1) % n_points_;
    --n_points_;
    ++n_dropped_;
  }
  points_[(first_point_ + n_points_) % points_.size()] = {t_s, chain_id_, chain_angle_rad_, r_body};
  ++n_points_;
  r_prev_ = r_body;
  has_prev_ = true;
  q_prev_ = q;
  t_prev_ = t_s;
  pending_rad_.setZero();
  pending_s_ = 0;
}

void StarRateIsolator::BreakChain() {
  if (chain_open_) end_cov_ += r_prev_;
  chain_open_ = false;
  has_prev_ = false;
  pending_rad_.setZero();
  pending_s_ = 0;
}

GyroVec StarRateIsolator::ResidualDph() const {
  GyroVec r = GyroVec::Zero(residual_rad_.size());
  if (covered_s_ <= 0) return r;
  for (int i = 0; i < r.size(); ++i) {
    if (use_[i]) r[i] = residual_rad_[i] / covered_s_ * kRadSToDph;
  }
  return r;
}

FaultFit StarRateIsolator::FitFault(int gi, double t_from_s, double t_now_s) const {
  FaultFit fit;
  // Unknowns: one offset per chain, then a (rad/s at t_now) and b (rad/s^2). The residual angle of a
  // sample at t is offset + a (t - t_now) + b (t - t_now)^2 / 2 + its star error. Each chain's offset
  // is eliminated (its weighted mean; the Schur complement of the normal equations), leaving 2 x 2
  // normal equations in (a, b) whose inverse is their marginal covariance: no storage per sample or
  // chain, so the fit allocates nothing.
  const Vec3 axis = axes_.row(gi).transpose();
  // A floor of 0.1 arcsec on the star error keeps a noiseless log's normal equations finite.
  const double floor_rad2 = std::pow(0.1 * kArcsecToRad, 2);
  auto in_span = [&](const Point& p) { return p.t_s >= t_from_s - 1e-9 && p.t_s <= t_now_s + 1e-9; };
  auto weight = [&](const Point& p) { return 1 / std::max(floor_rad2, axis.dot(p.r_body * axis)); };
  // Calls f(w, f1, f2, y) for each sample in the span, with the regressors x, x^2/2 and the residual
  // angle y centred on its chain's weighted mean.
  auto for_each_centred = [&](auto&& f) {
    int k = 0;
    while (k < n_points_) {
      if (!in_span(point(k))) {
        ++k;
        continue;
      }
      const int chain = point(k).chain;
      int end = k;
      double sw = 0, sx1 = 0, sx2 = 0, sy = 0;
      for (; end < n_points_ && point(end).chain == chain; ++end) {
        const Point& p = point(end);
        if (!in_span(p)) continue;
        const double w = weight(p), x = p.t_s - t_now_s;
        sw += w;
        sx1 += w * x;
        sx2 += w * 0.5 * x * x;
        sy += w * p.angle_rad[gi];
      }
      for (int j = k; j < end; ++j) {
        const Point& p = point(j);
        if (!in_span(p)) continue;
        const double x = p.t_s - t_now_s;
        f(weight(p), x - sx1 / sw, 0.5 * x * x - sx2 / sw, p.angle_rad[gi] - sy / sw);
      }
      k = end;
    }
  };
  int np = 0, nc = 0, last_chain = 0;
  for (int k = 0; k < n_points_; ++k) {
    const Point& p = point(k);
    if (!in_span(p)) continue;
    if (np == 0 || p.chain != last_chain) ++nc;
    last_chain = p.chain;
    ++np;
  }
  const int nu = nc + 2;
  if (np - nu < 1) return fit;
  Eigen::Matrix2d n = Eigen::Matrix2d::Zero();
  Eigen::Vector2d r = Eigen::Vector2d::Zero();
  for_each_centred([&](double w, double f1, double f2, double y) {
    const Eigen::Vector2d f(f1, f2);
    n += w * f * f.transpose();
    r += w * y * f;
  });
  const double det = n.determinant();
  if (!(det > 1e-14 * n(0, 0) * n(1, 1))) return fit;
  const Eigen::Matrix2d cov = n.inverse();
  const Eigen::Vector2d ab = cov * r;
  double chi2 = 0;
  for_each_centred([&](double w, double f1, double f2, double y) {
    const double e = y - ab[0] * f1 - ab[1] * f2;
    chi2 += w * e * e;
  });
  const double chi2_per_dof = chi2 / (np - nu);
  fit.value_dph = ab[0] * kRadSToDph;
  fit.ramp_dph_per_s = ab[1] * kRadSToDph;
  fit.sigma_dph = std::sqrt(cov(0, 0) * std::max(1.0, chi2_per_dof)) * kRadSToDph;
  fit.n = np;
  return fit;
}

void StarRateIsolator::ForgetBefore(double t_s) {
  while (n_points_ > 0 && point(0).t_s < t_s) {
    first_point_ = (first_point_ + 1) % static_cast<int>(points_.size());
    --n_points_;
  }
}

GyroVec StarRateIsolator::ResidualSigmaDph() const {
  GyroVec s = GyroVec::Constant(axes_.rows(), std::numeric_limits<double>::infinity());
  if (covered_s_ <= 0) return s;
  const Mat3 c = end_cov_ + (chain_open_ ? r_prev_ : Mat3::Zero());
  for (int i = 0; i < s.size(); ++i) {
    const Vec3 a = axes_.row(i).transpose();
    s[i] = std::sqrt(a.dot(c * a)) / covered_s_ * kRadSToDph;
  }
  return s;
}

double LargestImpliedRateDph(const GyroParity& v, const RateSolver& solver, const std::vector<bool>& use,
                             double jump_dph) {
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

int IsolateSequential(const GyroVec& r, const GyroVec& sigma_dph, double covered_s, const std::vector<bool>& use,
                      const FdiOptions& options) {
  if (covered_s < options.isolation_min_s) return -1;
  const int gi = IsolateFromResiduals(r, use, options);
  if (gi < 0) return -1;
  if (covered_s < options.isolation_window_s && !(std::abs(r[gi]) > options.isolation_sigma * sigma_dph[gi])) return -1;
  return gi;
}

int IsolateFromParity(const GyroParity& v, const GyroVec& jump, const std::vector<bool>& use,
                      const FdiOptions& options) {
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
