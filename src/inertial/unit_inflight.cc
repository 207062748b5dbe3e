#include "inertial/unit_inflight.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "inertial/propagate.h"

namespace ssiu {

void InflightCalOptions::Check() const {
  if (!(window_s > 0) || !std::isfinite(window_s)) throw InputError("calibrate-unit", "window_s must be positive");
  if (!(bias_block_s > 0) || !std::isfinite(bias_block_s))
    throw InputError("calibrate-unit", "bias_block_s must be positive");
}

Json InflightCalResult::ToJson() const {
  Json gs = Json::array();
  for (const auto& g : gyros) {
    gs.push_back({{"scale_factor_ppm", g.scale_factor_ppm},
                  {"scale_factor_sigma_ppm", g.scale_factor_sigma_ppm},
                  {"misalignment_arcsec", {g.misalignment_arcsec[0], g.misalignment_arcsec[1]}},
                  {"misalignment_sigma_arcsec", {g.misalignment_sigma_arcsec[0], g.misalignment_sigma_arcsec[1]}},
                  {"axis", {g.axis.x(), g.axis.y(), g.axis.z()}}});
  }
  return {{"status", ok ? "fitted" : "not_observable"},
          {"message", message},
          {"gyros", gs},
          {"n_windows", n_windows},
          {"n_bias_blocks", n_bias_blocks},
          {"chi2_per_dof", chi2_per_dof},
          {"best_combination_sigma", best_combination_sigma},
          {"worst_combination_sigma", worst_combination_sigma},
          {"unit", GyroUnitToJson(unit)}};
}

namespace {

// The two normals of an axis (GyroUnit::SensingAxis's convention).
void Normals(const Vec3& a, Vec3* u, Vec3* v) {
  Eigen::Index m;
  a.cwiseAbs().minCoeff(&m);
  *u = a.cross(Vec3::Unit(m)).normalized();
  *v = a.cross(*u);
}

// One linearised solve about `nominal` (its processor axes and calibration): the corrections on top of it.
InflightCalResult SolveOnce(const GyroLog& gyro, const StarTrackerLog& st, const GyroUnit& nominal,
                            double st_sigma_cross_arcsec, double st_sigma_roll_arcsec, const InflightCalOptions& o) {
  const int n = nominal.size();
  InflightCalResult res;
  res.unit = nominal;
  const GyroAxes h = nominal.ProcessorAxes();
  const std::vector<bool> all(n, true);
  const RateSolver solver(h, nominal.NoiseArw(), all);
  const GyroPinv& p = solver.Pinv();
  const GyroParity v = ParityMatrix(h, all);
  const int np = static_cast<int>(v.rows());
  std::vector<Vec3> u(n), w(n);
  for (int i = 0; i < n; ++i) Normals(h.row(i).transpose(), &u[i], &w[i]);
  // Angle white noise per gyro (rad^2 per s of integration).
  GyroVec arw2(n);
  for (int i = 0; i < n; ++i) arw2[i] = std::pow(nominal.NoiseArw()[i] * kDegToRad / 60.0, 2);

  // Windows between star fixes, every other one (no star error shared by two windows).
  struct Window {
    size_t a, b;
  };
  std::vector<Window> windows;
  for (size_t j = 0; j + 1 < st.t_s.size();) {
    size_t b = j + 1;
    while (b < st.t_s.size() && st.t_s[b] - st.t_s[j] < o.window_s - 1e-9) ++b;
    if (b >= st.t_s.size()) break;
    if (st.t_s[b] - st.t_s[j] <= 1.5 * o.window_s) windows.push_back({j, b});
    j = b + 1;
  }
  const double t0 = gyro.t_s.front();
  const int n_blocks = std::max(1, static_cast<int>(std::ceil((gyro.t_s.back() - t0) / o.bias_block_s)));
  const int n_par = 3 * n + n * n_blocks;
  const int rows_per = 3 + np;
  Eigen::MatrixXd jac = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(windows.size()) * rows_per, n_par);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(jac.rows());
  int used = 0;
  const double kSfToRel = 1e-6, kAsToRad = kArcsecToRad, kDphToRad = kDphToRadS;
  size_t k = 0;
  for (const Window& win : windows) {
    const double ta = st.t_s[win.a], tb = st.t_s[win.b];
    while (k < gyro.t_s.size() && gyro.t_s[k] <= ta + 1e-9) ++k;
    size_t k_end = k;
    while (k_end < gyro.t_s.size() && gyro.t_s[k_end] <= tb + 1e-9) ++k_end;
    if (k_end - k < 2) continue;
    const int blk = std::min(n_blocks - 1, static_cast<int>((0.5 * (ta + tb) - t0) / o.bias_block_s));
    // Propagate the body from a to each sample; keep each sample's rate, rotation and interval.
    std::vector<Mat3> r_ak;  // body at k -> body at a
    std::vector<Vec3> rate;
    std::vector<GyroVec> g;
    std::vector<double> dt;
    Quat q_rel = Quat::Identity();
    for (size_t s = k; s < k_end; ++s) {
      const double d = gyro.t_s[s] - (s > 0 ? gyro.t_s[s - 1] : ta);
      GyroVec gs = gyro.rates_dph[s];
      nominal.RemoveCalibratedErrors(&gs);
      if (!gs.allFinite()) continue;
      const Vec3 wr = p * gs * kDphToRadS;
      q_rel = (q_rel * QuatFromRotationVector(wr * d)).normalized();
      r_ak.push_back(q_rel.toRotationMatrix());
      rate.push_back(wr);
      g.push_back(gs * kDphToRadS);
      dt.push_back(d);
    }
    if (rate.size() < 2) continue;
    const Mat3 r_ab = r_ak.back();  // body at b -> body at a
    const Quat q_gyro_b = (st.q_inertial_from_body[win.a] * q_rel).normalized();
    Quat dq = q_gyro_b.conjugate() * st.q_inertial_from_body[win.b];
    if (dq.w() < 0) dq.coeffs() *= -1;
    const Vec3 dphi = 2 * dq.vec();
    const int r0 = used * rows_per;
    y.segment<3>(r0) = dphi;
    Mat3 cov = Mat3::Zero();
    double span = 0;
    Eigen::VectorXd parity_mean = Eigen::VectorXd::Zero(np);
    Eigen::MatrixXd parity_reg = Eigen::MatrixXd::Zero(np, n_par);
    for (size_t s = 0; s < rate.size(); ++s) {
      const Mat3 c_bk = r_ab.transpose() * r_ak[s];  // body at k -> body at b
      const Vec3 wk = rate[s];
      for (int i = 0; i < n; ++i) {
        const Vec3 col = -c_bk * p.col(i) * dt[s];
        const Vec3 a = h.row(i).transpose();
        jac.block<3, 1>(r0, 3 * i) += col * (kSfToRel * a.dot(wk));
        jac.block<3, 1>(r0, 3 * i + 1) += col * (kAsToRad * u[i].dot(wk));
        jac.block<3, 1>(r0, 3 * i + 2) += col * (kAsToRad * w[i].dot(wk));
        jac.block<3, 1>(r0, 3 * n + n * blk + i) += col * kDphToRad;
        if (np > 0) {
          parity_reg.col(3 * i) += v.col(i) * (kSfToRel * a.dot(wk)) * dt[s];
          parity_reg.col(3 * i + 1) += v.col(i) * (kAsToRad * u[i].dot(wk)) * dt[s];
          parity_reg.col(3 * i + 2) += v.col(i) * (kAsToRad * w[i].dot(wk)) * dt[s];
          parity_reg.col(3 * n + n * blk + i) += v.col(i) * kDphToRad * dt[s];
        }
      }
      // The gyros' white noise over this sample, as angle (P diag(ARW^2 dt) P'), seen at b.
      const Mat3 pw = p * arw2.head(n).asDiagonal() * p.transpose() * dt[s];
      cov += c_bk * pw * c_bk.transpose();
      if (np > 0) parity_mean += v * g[s] * dt[s];
      span += dt[s];
    }
    // Star errors at both ends (cross-boresight about body x, y; roll about z), the first seen at b.
    auto st_cov = [&](size_t j) {
      const double sc = (st.sigma_cross_arcsec.empty() ? st_sigma_cross_arcsec : st.sigma_cross_arcsec[j]) * kAsToRad;
      const double sr = (st.sigma_roll_arcsec.empty() ? st_sigma_roll_arcsec : st.sigma_roll_arcsec[j]) * kAsToRad;
      return Mat3(Vec3(sc * sc, sc * sc, sr * sr).asDiagonal());
    };
    cov += r_ab.transpose() * st_cov(win.a) * r_ab + st_cov(win.b);
    Eigen::MatrixXd full = Eigen::MatrixXd::Zero(rows_per, rows_per);
    full.topLeftCorner<3, 3>() = cov;
    if (np > 0) {
      y.segment(r0 + 3, np) = parity_mean / span;
      jac.block(r0 + 3, 0, np, n_par) = parity_reg / span;
      // Mean parity of white noise over the window: V diag(ARW^2) V' / span.
      full.bottomRightCorner(np, np) = v * arw2.head(n).asDiagonal() * v.transpose() / span;
    }
    // Whiten this window's rows.
    const Eigen::LLT<Eigen::MatrixXd> llt(full);
    if (llt.info() != Eigen::Success) continue;
    jac.middleRows(r0, rows_per) = llt.matrixL().solve(jac.middleRows(r0, rows_per));
    y.segment(r0, rows_per) = llt.matrixL().solve(y.segment(r0, rows_per));
    ++used;
  }
  res.n_windows = used;
  res.n_bias_blocks = n_blocks;
  const Eigen::MatrixXd js = jac.topRows(static_cast<Eigen::Index>(used) * rows_per);
  const Eigen::VectorXd ys = y.head(js.rows());
  // Blocks without a window carry no information: they are left out of the solve.
  std::vector<int> keep;
  for (int c = 0; c < n_par; ++c) {
    if (c < 3 * n || js.col(c).squaredNorm() > 0) keep.push_back(c);
  }
  const int nk = static_cast<int>(keep.size());
  if (js.rows() < nk + 3) {
    res.message = "too few star windows (" + std::to_string(used) + ") for " + std::to_string(nk) + " parameters";
    return res;
  }
  Eigen::MatrixXd jk(js.rows(), nk);
  for (int c = 0; c < nk; ++c) jk.col(c) = js.col(keep[c]);
  const Eigen::MatrixXd info = jk.transpose() * jk;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig_info(info);
  if (!(eig_info.eigenvalues()(0) > 1e-12 * eig_info.eigenvalues()(nk - 1))) {
    res.message = "scale factors and axes not observable: the body must turn about three independent axes";
    return res;
  }
  const Eigen::VectorXd beta = info.ldlt().solve(jk.transpose() * ys);
  const double rss = (ys - jk * beta).squaredNorm();
  res.chi2_per_dof = rss / std::max<Eigen::Index>(1, js.rows() - nk);
  const Eigen::MatrixXd cov = info.inverse() * std::max(1.0, res.chi2_per_dof);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig_cov(cov.topLeftCorner(3 * n, 3 * n));
  res.best_combination_sigma = std::sqrt(std::max(0.0, eig_cov.eigenvalues()(0)));
  res.worst_combination_sigma = std::sqrt(std::max(0.0, eig_cov.eigenvalues()(3 * n - 1)));
  res.unit.calibrated = true;
  for (int i = 0; i < n; ++i) {
    InflightGyroCal gc;
    gc.scale_factor_ppm = beta[3 * i];
    gc.misalignment_arcsec[0] = beta[3 * i + 1], gc.misalignment_arcsec[1] = beta[3 * i + 2];
    gc.scale_factor_sigma_ppm = std::sqrt(cov(3 * i, 3 * i));
    gc.misalignment_sigma_arcsec[0] = std::sqrt(cov(3 * i + 1, 3 * i + 1));
    gc.misalignment_sigma_arcsec[1] = std::sqrt(cov(3 * i + 2, 3 * i + 2));
    const Vec3 a = h.row(i).transpose();
    const Vec3 m = a + kAsToRad * (gc.misalignment_arcsec[0] * u[i] + gc.misalignment_arcsec[1] * w[i]);
    gc.axis = m.normalized();
    // The model's (1 + S)(n + mu u + nu v) is (1 + S) |m| along the unit axis: the scale factor of
    // unit.json's convention (GyroErrorModel, a unit sensing axis).
    gc.scale_factor_ppm = 1e6 * ((1 + 1e-6 * gc.scale_factor_ppm) * m.norm() - 1);
    // On top of what the nominal unit already removes (a bench-calibrated one): the scale factors
    // compose, the fitted axis replaces the processor's.
    GyroErrorModel& e = res.unit.gyros[i];
    const double s0 = nominal.calibrated ? e.scale_factor_ppm : 0.0;
    e.scale_factor_ppm = s0 + gc.scale_factor_ppm + 1e-6 * s0 * gc.scale_factor_ppm;
    if (!nominal.calibrated) {
      e.bias_dph = 0, e.scale_factor_asymmetry_ppm = 0, e.scale_factor_nonlinearity_ppm_per_dps = 0;
    }
    e.misalignment_arcsec[0] = e.misalignment_arcsec[1] = 0;
    res.unit.axes_body[i] = gc.axis;
    res.gyros.push_back(gc);
  }
  res.ok = true;
  return res;
}

}  // namespace

InflightCalResult CalibrateUnitInFlight(const GyroLog& gyro, const StarTrackerLog& st, const GyroUnit& nominal,
                                        double st_sigma_cross_arcsec, double st_sigma_roll_arcsec,
                                        const InflightCalOptions& o) {
  o.Check();
  nominal.Check("unit");
  if (gyro.body_rates) throw InputError(gyro.file, "--calibrate-unit needs the gyros' outputs g1_dph..gN_dph");
  // Gauss-Newton: the model is linear in the errors about the unit it propagates with; the rates that
  // build its regressors carry the errors too (a tilt of 1e-3 rad times a rate error of 1e-3 is 1 ppm),
  // so it is solved again about the calibrated unit until the corrections are far below their sigmas.
  InflightCalResult res = SolveOnce(gyro, st, nominal, st_sigma_cross_arcsec, st_sigma_roll_arcsec, o);
  for (int it = 0; it < 3 && res.ok; ++it) {
    InflightCalResult next = SolveOnce(gyro, st, res.unit, st_sigma_cross_arcsec, st_sigma_roll_arcsec, o);
    if (!next.ok) break;
    res = next;
  }
  if (!res.ok) return res;
  // The estimates against the nominal unit's own processor axes and scale factors.
  const GyroAxes h0 = nominal.ProcessorAxes();
  for (int i = 0; i < nominal.size(); ++i) {
    const Vec3 n0 = h0.row(i).transpose(), a = res.unit.axes_body[i];
    Vec3 u, v;
    Normals(n0, &u, &v);
    InflightGyroCal& g = res.gyros[i];
    g.axis = a;
    g.misalignment_arcsec[0] = a.dot(u) / a.dot(n0) * kRadToArcsec;
    g.misalignment_arcsec[1] = a.dot(v) / a.dot(n0) * kRadToArcsec;
    const double s0 = nominal.calibrated ? nominal.gyros[i].scale_factor_ppm : 0.0;
    g.scale_factor_ppm = 1e6 * ((1 + 1e-6 * res.unit.gyros[i].scale_factor_ppm) / (1 + 1e-6 * s0) - 1);
  }
  return res;
}

}  // namespace ssiu
