#include "inertial/unit_calibrator.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "inertial/propagate.h"

namespace ssiu {

void InflightCalOptions::Check() const {
  auto positive = [](double v) { return v > 0 && std::isfinite(v); };
  if (!positive(window_s)) throw InputError("calibrate-unit", "window_s must be positive");
  if (!positive(bias_block_s)) throw InputError("calibrate-unit", "bias_block_s must be positive");
  if (!(prior_scale_factor_sigma_ppm >= 0) || !std::isfinite(prior_scale_factor_sigma_ppm))
    throw InputError("calibrate-unit", "prior_scale_factor_sigma_ppm must be >= 0");
  if (!(prior_misalignment_sigma_arcsec >= 0) || !std::isfinite(prior_misalignment_sigma_arcsec))
    throw InputError("calibrate-unit", "prior_misalignment_sigma_arcsec must be >= 0");
}

const char* UnitCalStatusName(UnitCalStatus s) {
  switch (s) {
    case UnitCalStatus::kOff:
      return "off";
    case UnitCalStatus::kAccumulating:
      return "accumulating";
    case UnitCalStatus::kNotObservable:
      return "not_observable";
    case UnitCalStatus::kEstimated:
      return "estimated";
    case UnitCalStatus::kApplied:
      return "applied";
  }
  return "unknown";
}

Json UnitCalStateToJson(const UnitCalState& s) {
  Json j = {{"status", UnitCalStatusName(s.status)},
            {"n_windows", s.n_windows},
            {"n_bias_blocks", s.n_bias_blocks},
            {"windows_dropped", s.windows_dropped},
            {"chi2_per_dof", s.chi2_per_dof},
            {"best_combination_sigma", s.best_combination_sigma},
            {"worst_combination_sigma", s.worst_combination_sigma}};
  Json gs = Json::array();
  if (s.status == UnitCalStatus::kEstimated || s.status == UnitCalStatus::kApplied) {
    for (int i = 0; i < s.n_gyros; ++i) {
      gs.push_back(
          {{"scale_factor_ppm", s.scale_factor_ppm[i]},
           {"scale_factor_sigma_ppm", s.scale_factor_sigma_ppm[i]},
           {"misalignment_arcsec", {s.misalignment_arcsec[i][0], s.misalignment_arcsec[i][1]}},
           {"misalignment_sigma_arcsec", {s.misalignment_sigma_arcsec[i][0], s.misalignment_sigma_arcsec[i][1]}}});
    }
  }
  j["gyros"] = gs;
  return j;
}

void AxisNormals(const Vec3& a, Vec3* u, Vec3* v) {
  Eigen::Index m;
  a.cwiseAbs().minCoeff(&m);
  *u = a.cross(Vec3::Unit(m)).normalized();
  *v = a.cross(*u);
}

namespace {
constexpr double kPpm = 1e-6;
}  // namespace

InflightCalibrator::InflightCalibrator(const GyroUnit& unit, const InflightCalOptions& options) : opt_(options) {
  opt_.Check();
  unit.Check("unit");
  n_ = unit.size();
  if (n_ < 4) throw InputError("unit", "in-flight calibration needs 4 or more gyros (a parity)");
  h_ = unit.ProcessorAxes();
  const std::vector<bool> all(n_, true);
  const RateSolver solver(h_, unit.NoiseArw(), all);
  p_ = solver.Pinv();
  v_ = ParityMatrix(h_, all);
  np_ = static_cast<int>(v_.rows());
  for (int i = 0; i < n_; ++i) AxisNormals(h_.row(i).transpose(), &u_[i], &w_[i]);
  arw2_.resize(n_);
  for (int i = 0; i < n_; ++i) arw2_[i] = std::pow(unit.NoiseArw()[i] * kDegToRad / 60.0, 2);
  pwp_ = p_ * arw2_.asDiagonal() * p_.transpose();
  vwv_ = v_ * arw2_.asDiagonal() * v_.transpose();
  const int m = 4 * n_;
  info_ = ParMat::Zero(m, m);
  eta_ = ParVec::Zero(m);
  a_.setZero(3, m);
  b_.setZero(np_, m);
  parity_sum_ = GyroVec::Zero(np_);
  g_prev_ = GyroVec::Zero(n_);
}

void InflightCalibrator::BreakWindow() {
  if (open_) ++dropped_;
  open_ = false;
}

void InflightCalibrator::Accumulate(const GyroVec& g, const Vec3& w, double dt) {
  q_rel_ = (q_rel_ * QuatFromRotationVector(w * dt)).normalized();
  const Mat3 r_ak = q_rel_.toRotationMatrix();  // body at this sample -> body at the window's start
  for (int i = 0; i < n_; ++i) {
    const Vec3 col = r_ak * p_.col(i) * dt;
    const double c[4] = {kPpm * h_.row(i).dot(w), kArcsecToRad * u_[i].dot(w), kArcsecToRad * w_[i].dot(w), kDphToRadS};
    for (int k = 0; k < 3; ++k) a_.col(3 * i + k) += col * c[k];
    a_.col(3 * n_ + i) += col * c[3];
    if (np_ > 0) {
      for (int k = 0; k < 3; ++k) b_.col(3 * i + k) += v_.col(i) * (c[k] * dt);
      b_.col(3 * n_ + i) += v_.col(i) * (c[3] * dt);
    }
  }
  q_noise_ += r_ak * (pwp_ * dt) * r_ak.transpose();
  if (np_ > 0) parity_sum_ += v_ * g * dt;
  span_ += dt;
  ++n_samples_;
}

void InflightCalibrator::AddGyro(double t_s, const GyroVec& g_dph) {
  if (n_ == 0) return;
  if (g_dph.size() != n_ || !g_dph.allFinite() || !std::isfinite(t_s) || (have_prev_ && t_s <= t_prev_)) {
    BreakWindow();
    have_prev_ = false;
    return;
  }
  if (!have_t0_) have_t0_ = true, t0_ = t_s;
  const GyroVec g = g_dph * kDphToRadS;
  const Vec3 w = p_ * g;
  // The part of the sample's interval inside the window (all of it but for the first sample).
  if (open_ && t_s > t_a_) {
    const double from = have_prev_ ? std::max(t_prev_, t_a_) : t_a_;
    Accumulate(g, w, t_s - from);
  }
  have_prev_ = true;
  t_prev_ = t_s;
  g_prev_ = g;
  w_prev_ = w;
}

bool InflightCalibrator::AddFix(double t_s, const Quat& q, const Mat3& cov) {
  if (n_ == 0 || !std::isfinite(t_s) || !q.coeffs().allFinite() || !cov.allFinite()) return false;
  if (open_) {
    if (t_s - t_a_ < opt_.window_s - 1e-9) return false;  // inside the window
    // A fix between samples: the last rate held up to it (the next window starts at a later fix).
    if (have_prev_ && t_s > t_prev_ + 1e-12 && t_prev_ >= t_a_) Accumulate(g_prev_, w_prev_, t_s - t_prev_);
    open_ = false;
    if (t_s - t_a_ > 1.5 * opt_.window_s || n_samples_ < 2) {
      ++dropped_;
      return false;
    }
    CloseWindow(t_s, q, cov);
    return true;
  }
  open_ = true;
  t_a_ = t_s;
  q_a_ = q.normalized();
  cov_a_ = cov;
  q_rel_ = Quat::Identity();
  q_noise_.setZero();
  a_.setZero();
  b_.setZero();
  parity_sum_.setZero();
  span_ = 0;
  n_samples_ = 0;
  return false;
}

void InflightCalibrator::CloseWindow(double t_b, const Quat& q_b, const Mat3& cov_b) {
  const int m = 4 * n_, rows = 3 + np_;
  const Mat3 r_ab = q_rel_.toRotationMatrix();  // body at b -> body at a
  Quat dq = (q_a_ * q_rel_).normalized().conjugate() * q_b.normalized();
  if (dq.w() < 0) dq.coeffs() *= -1;
  using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxGyros + 3, kMaxParams>;
  using RowVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxGyros + 3, 1>;
  using RowCov = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxGyros + 3, kMaxGyros + 3>;
  RowMat j(rows, m);
  RowVec y(rows);
  RowCov c = RowCov::Zero(rows, rows);
  j.topRows<3>().noalias() = -r_ab.transpose() * a_;
  y.head<3>() = 2 * dq.vec();
  // The gyros' white noise and the star errors at both ends, all seen in the body at b.
  c.topLeftCorner<3, 3>() = r_ab.transpose() * (q_noise_ + cov_a_) * r_ab + cov_b;
  if (np_ > 0) {
    j.bottomRows(np_) = b_ / span_;
    y.tail(np_) = parity_sum_ / span_;
    c.bottomRightCorner(np_, np_) = vwv_ / span_;  // mean parity of white noise over the window
  }
  const Eigen::LLT<RowCov> llt(c);
  if (llt.info() != Eigen::Success) {
    ++dropped_;
    return;
  }
  llt.matrixL().solveInPlace(j);
  llt.matrixL().solveInPlace(y);
  // The block this window falls in (by its middle): a new block's biases are new parameters.
  const double mid = 0.5 * (t_a_ + t_b) - t0_;
  const long block = static_cast<long>(std::floor(mid / opt_.bias_block_s));
  if (block != block_ && block_windows_ > 0) {
    EliminateBiases(&info_, &eta_, &yy_);
    block_windows_ = 0;
  }
  block_ = block;
  if (block_windows_ == 0) ++n_blocks_;
  info_.noalias() += j.transpose() * j;
  eta_.noalias() += j.transpose() * y;
  yy_ += y.squaredNorm();
  rows_ += rows;
  ++n_windows_;
  ++block_windows_;
}

void InflightCalibrator::EliminateBiases(ParMat* info, ParVec* eta, double* yy) const {
  const int t = 3 * n_;
  using BiasMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxGyros, kMaxGyros>;
  const BiasMat lbb = info->block(t, t, n_, n_);
  const Eigen::LDLT<BiasMat> ldlt(lbb);
  // Lbb^-1 [Lbc, eta_b]: the Schur complement of the block's biases.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxGyros, 3 * kMaxGyros + 1> rhs(n_, t + 1);
  rhs.leftCols(t) = info->block(t, 0, n_, t);
  rhs.col(t) = eta->segment(t, n_);
  const decltype(rhs) x = ldlt.solve(rhs);
  info->topLeftCorner(t, t).noalias() -= info->block(0, t, t, n_) * x.leftCols(t);
  eta->head(t).noalias() -= info->block(0, t, t, n_) * x.col(t);
  *yy -= eta->segment(t, n_).dot(x.col(t));
  info->rightCols(n_).setZero();
  info->bottomRows(n_).setZero();
  eta->tail(n_).setZero();
}

UnitCalState InflightCalibrator::Estimate() const {
  UnitCalState s;
  s.n_gyros = n_;
  s.n_windows = n_windows_;
  s.n_bias_blocks = n_blocks_;
  s.windows_dropped = dropped_;
  s.status = UnitCalStatus::kAccumulating;
  const int t = 3 * n_;
  if (n_ == 0 || rows_ < t + n_ * n_blocks_ + 3) return s;
  ParMat info = info_;
  ParVec eta = eta_;
  double yy = yy_;
  if (block_windows_ > 0) EliminateBiases(&info, &eta, &yy);
  const ParMat lcc = info.topLeftCorner(t, t);
  const Eigen::SelfAdjointEigenSolver<ParMat> eig_info(lcc, Eigen::EigenvaluesOnly);
  if (!(eig_info.eigenvalues()(0) > 1e-12 * eig_info.eigenvalues()(t - 1))) {
    s.status = UnitCalStatus::kNotObservable;
    return s;
  }
  // The prior's information on top (posterior mean and covariance); the residual is the windows'.
  ParMat post = lcc;
  for (int i = 0; i < n_; ++i) {
    const double ps = opt_.prior_scale_factor_sigma_ppm, pm = opt_.prior_misalignment_sigma_arcsec;
    if (ps > 0) post(3 * i, 3 * i) += 1 / (ps * ps);
    if (pm > 0) post(3 * i + 1, 3 * i + 1) += 1 / (pm * pm), post(3 * i + 2, 3 * i + 2) += 1 / (pm * pm);
  }
  const Eigen::LDLT<ParMat> ldlt(post);
  const ParVec beta = ldlt.solve(eta.head(t));
  const double rss = std::max(0.0, yy - 2 * eta.head(t).dot(beta) + beta.dot(lcc * beta));
  const long dof = rows_ - (t + n_ * n_blocks_);
  s.chi2_per_dof = rss / static_cast<double>(std::max(1L, dof));
  const ParMat cov = ldlt.solve(ParMat::Identity(t, t)) * std::max(1.0, s.chi2_per_dof);
  const Eigen::SelfAdjointEigenSolver<ParMat> eig_cov(cov, Eigen::EigenvaluesOnly);
  s.best_combination_sigma = std::sqrt(std::max(0.0, eig_cov.eigenvalues()(0)));
  s.worst_combination_sigma = std::sqrt(std::max(0.0, eig_cov.eigenvalues()(t - 1)));
  for (int i = 0; i < n_; ++i) {
    s.scale_factor_ppm[i] = beta[3 * i];
    s.scale_factor_sigma_ppm[i] = std::sqrt(cov(3 * i, 3 * i));
    for (int k = 0; k < 2; ++k) {
      s.misalignment_arcsec[i][k] = beta[3 * i + 1 + k];
      s.misalignment_sigma_arcsec[i][k] = std::sqrt(cov(3 * i + 1 + k, 3 * i + 1 + k));
    }
  }
  s.status = UnitCalStatus::kEstimated;
  return s;
}

Vec3 InflightCalibrator::OutputError(const UnitCalState& s, int i) const {
  return kPpm * s.scale_factor_ppm[i] * h_.row(i).transpose() +
         kArcsecToRad * (s.misalignment_arcsec[i][0] * u_[i] + s.misalignment_arcsec[i][1] * w_[i]);
}

}  // namespace ssiu
