#include "inertial/gyro_unit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace ssiu {

double GyroErrorModel::GaussMarkovSigmaDph() const {
  const int n = static_cast<int>(bias_instability_tau_s.size());
  if (n == 0 || bias_instability_dph == 0) return 0.0;
  return bias_instability_dph / (0.62 * std::sqrt(static_cast<double>(n)));
}

double GyroErrorModel::BiasDriftDphPerSqrtS() const {
  const double s = GaussMarkovSigmaDph();
  double q = std::pow(rrw_dph_per_sqrt_h / 60.0, 2);  // (deg/h)/sqrt(h) -> (deg/h)/sqrt(s)
  for (double tau : bias_instability_tau_s) q += 2 * s * s / tau;
  return std::sqrt(q);
}

void GyroErrorModel::Check(const std::string& what) const {
  auto bad = [&](const std::string& field, const std::string& why) { throw InputError(what, field + " " + why); };
  const double finite_fields[] = {bias_dph,
                                  arw_deg_per_sqrt_h,
                                  bias_instability_dph,
                                  rrw_dph_per_sqrt_h,
                                  quantization_arcsec,
                                  scale_factor_ppm,
                                  scale_factor_nonlinearity_ppm_per_dps,
                                  scale_factor_asymmetry_ppm,
                                  misalignment_arcsec[0],
                                  misalignment_arcsec[1],
                                  time_delay_s};
  for (double v : finite_fields) {
    if (!std::isfinite(v)) bad("error model", "has a non-finite term");
  }
  if (arw_deg_per_sqrt_h < 0) bad("arw_deg_per_sqrt_h", "must be >= 0");
  if (bias_instability_dph < 0) bad("bias_instability_dph", "must be >= 0");
  if (rrw_dph_per_sqrt_h < 0) bad("rrw_dph_per_sqrt_h", "must be >= 0");
  if (quantization_arcsec < 0) bad("quantization_arcsec", "must be >= 0");
  if (time_delay_s < 0 || time_delay_s > 1) bad("time_delay_s", "must be in [0, 1] s");
  for (double tau : bias_instability_tau_s) {
    if (!(tau > 0) || !std::isfinite(tau)) bad("bias_instability_tau_s", "must be positive");
  }
  for (double k : thermal.k_dph) {
    if (!std::isfinite(k)) bad("thermal_k_dph", "must be finite");
  }
  if (!(thermal.t1_c != thermal.t0_c) || !(thermal.g0_c_per_min > 0)) {
    bad("thermal", "needs t1_c != t0_c and g0_c_per_min > 0");
  }
}

GyroAxes GyroUnit::Axes() const {
  GyroAxes h(size(), 3);
  for (int i = 0; i < size(); ++i) h.row(i) = axes_body[i].transpose();
  return h;
}

Vec3 GyroUnit::SensingAxis(int i) const {
  const Vec3& a = axes_body[i];
  Eigen::Index m;
  a.cwiseAbs().minCoeff(&m);
  const Vec3 u = a.cross(Vec3::Unit(m)).normalized();
  const Vec3 v = a.cross(u);
  const auto& e = gyros[i];
  return (a + e.misalignment_arcsec[0] * kArcsecToRad * u + e.misalignment_arcsec[1] * kArcsecToRad * v).normalized();
}

GyroAxes GyroUnit::SensingAxes() const {
  GyroAxes h(size(), 3);
  for (int i = 0; i < size(); ++i) h.row(i) = SensingAxis(i).transpose();
  return h;
}

void GyroUnit::RemoveCalibratedErrors(GyroVec* g) const {
  if (!calibrated) return;
  for (int i = 0; i < size() && i < g->size(); ++i) {
    const auto& e = gyros[i];
    const double w = (*g)[i] - e.bias_dph;
    // The scale terms are 1e-4 at most: evaluating them at the measured rate is exact to 1e-8.
    const double sf = 1 + 1e-6 * (e.scale_factor_ppm +
                                  e.scale_factor_asymmetry_ppm * (w > 0   ? 1
                                                                  : w < 0 ? -1
                                                                          : 0) +
                                  e.scale_factor_nonlinearity_ppm_per_dps * std::abs(w) / 3600.0);
    (*g)[i] = w / sf;
  }
}

GyroVec GyroUnit::NoiseArw() const {
  double smallest = 0;
  for (const auto& g : gyros) {
    if (g.arw_deg_per_sqrt_h > 0 && (smallest == 0 || g.arw_deg_per_sqrt_h < smallest)) smallest = g.arw_deg_per_sqrt_h;
  }
  if (smallest == 0) smallest = 1;
  GyroVec s(size());
  for (int i = 0; i < size(); ++i) s[i] = gyros[i].arw_deg_per_sqrt_h > 0 ? gyros[i].arw_deg_per_sqrt_h : smallest;
  return s;
}

void GyroUnit::Check(const std::string& file) const {
  if (size() < 3 || size() > kMaxGyros)
    throw InputError(file, "gyros: need 3 to 6 gyros, got " + std::to_string(size()));
  if (gyros.size() != axes_body.size()) throw InputError(file, "gyros: one error model per axis");
  if (!(rate_hz > 0) || !std::isfinite(rate_hz)) throw InputError(file, "rate_hz must be positive");
  for (int i = 0; i < size(); ++i) {
    const std::string what = file + ": gyro " + std::to_string(i + 1);
    if (!axes_body[i].allFinite() || std::abs(axes_body[i].norm() - 1) > 1e-6)
      throw InputError(what, "axis must be a unit vector");
    gyros[i].Check(what);
  }
  // The smallest singular value of H below 1e-3: the smallest eigenvalue of H^T H below 1e-6 (a 3 x 3
  // eigenproblem; an SVD of H costs the library's build more than all the rest of this file).
  const GyroAxes h = Axes();
  const Mat3 hth = h.transpose() * h;
  if (Eigen::SelfAdjointEigenSolver<Mat3>(hth, Eigen::EigenvaluesOnly).eigenvalues()(0) < 1e-6)
    throw InputError(file, "gyro axes do not span three dimensions");
}

GyroUnit DefaultFourFogUnit() {
  GyroUnit u;
  u.axes_body = {Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ(), Vec3(1, 1, 1).normalized()};
  u.gyros.assign(4, GyroErrorModel{});
  u.rate_hz = 100;
  return u;
}

GyroUnit OrthogonalTriad(double arw_deg_per_sqrt_h, double bias_instability_dph) {
  GyroUnit u;
  u.axes_body = {Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  GyroErrorModel m;
  m.arw_deg_per_sqrt_h = arw_deg_per_sqrt_h;
  m.bias_instability_dph = bias_instability_dph;
  u.gyros.assign(3, m);
  return u;
}

namespace {

// Fields present in `j` override those of `m` (so a "default" block and per-gyro blocks compose).
void ApplyErrorModel(const Json& j, GyroErrorModel* m, const std::string& what, bool with_axis) {
  if (!j.is_object()) throw InputError(what, "gyro entry must be an object");
  std::vector<std::string> keys = {"bias_dph",
                                   "arw_deg_per_sqrt_h",
                                   "bias_instability_dph",
                                   "bias_instability_tau_s",
                                   "rrw_dph_per_sqrt_h",
                                   "quantization_arcsec",
                                   "scale_factor_ppm",
                                   "scale_factor_nonlinearity_ppm_per_dps",
                                   "scale_factor_asymmetry_ppm",
                                   "misalignment_arcsec",
                                   "time_delay_s",
                                   "thermal_k_dph",
                                   "thermal_t0_c",
                                   "thermal_t1_c",
                                   "thermal_g0_c_per_min",
                                   "magnetic_dph_per_ut"};
  if (with_axis) keys.push_back("axis");
  CheckKeys(j, keys, what);
  m->bias_dph = JsonNumberOr(j, "bias_dph", m->bias_dph, what);
  m->arw_deg_per_sqrt_h = JsonNumberOr(j, "arw_deg_per_sqrt_h", m->arw_deg_per_sqrt_h, what);
  m->bias_instability_dph = JsonNumberOr(j, "bias_instability_dph", m->bias_instability_dph, what);
  if (j.contains("bias_instability_tau_s"))
    m->bias_instability_tau_s = JsonNumbers(j, "bias_instability_tau_s", -1, what);
  m->rrw_dph_per_sqrt_h = JsonNumberOr(j, "rrw_dph_per_sqrt_h", m->rrw_dph_per_sqrt_h, what);
  m->quantization_arcsec = JsonNumberOr(j, "quantization_arcsec", m->quantization_arcsec, what);
  m->scale_factor_ppm = JsonNumberOr(j, "scale_factor_ppm", m->scale_factor_ppm, what);
  m->scale_factor_nonlinearity_ppm_per_dps =
      JsonNumberOr(j, "scale_factor_nonlinearity_ppm_per_dps", m->scale_factor_nonlinearity_ppm_per_dps, what);
  m->scale_factor_asymmetry_ppm = JsonNumberOr(j, "scale_factor_asymmetry_ppm", m->scale_factor_asymmetry_ppm, what);
  if (j.contains("misalignment_arcsec")) {
    const auto v = JsonNumbers(j, "misalignment_arcsec", -1, what);
    if (v.size() != 2) throw InputError(what, "misalignment_arcsec must have 2 numbers");
    m->misalignment_arcsec[0] = v[0];
    m->misalignment_arcsec[1] = v[1];
  }
  m->time_delay_s = JsonNumberOr(j, "time_delay_s", m->time_delay_s, what);
  if (j.contains("thermal_k_dph")) {
    const auto v = JsonNumbers(j, "thermal_k_dph", -1, what);
    if (v.size() != ThermalDriftModel::kNumTerms)
      throw InputError(what, "thermal_k_dph must have 10 numbers (K00..K03)");
    std::copy(v.begin(), v.end(), m->thermal.k_dph.begin());
  }
  m->thermal.t0_c = JsonNumberOr(j, "thermal_t0_c", m->thermal.t0_c, what);
  m->thermal.t1_c = JsonNumberOr(j, "thermal_t1_c", m->thermal.t1_c, what);
  m->thermal.g0_c_per_min = JsonNumberOr(j, "thermal_g0_c_per_min", m->thermal.g0_c_per_min, what);
  if (j.contains("magnetic_dph_per_ut")) {
    const auto v = JsonNumbers(j, "magnetic_dph_per_ut", -1, what);
    if (v.size() != 3) throw InputError(what, "magnetic_dph_per_ut must be [along, across, vertical]");
    m->magnetic = {v[0], v[1], v[2]};
  }
}

}  // namespace

GyroUnit GyroUnitFromJson(const Json& j, const std::string& file) {
  if (!j.is_object()) throw InputError(file, "unit must be a JSON object");
  CheckKeys(j, {"rate_hz", "gyros", "default", "comment", "calibrated"}, file);
  if (!j.contains("gyros") || !j["gyros"].is_array()) throw InputError(file, "missing array 'gyros'");
  GyroErrorModel base;
  if (j.contains("default")) ApplyErrorModel(j["default"], &base, file + ": default", false);
  GyroUnit u;
  u.rate_hz = JsonNumberOr(j, "rate_hz", 100.0, file);
  u.calibrated = JsonBoolOr(j, "calibrated", false, file);
  int i = 0;
  for (const auto& g : j["gyros"]) {
    const std::string what = file + ": gyro " + std::to_string(++i);
    if (!g.is_object() || !g.contains("axis")) throw InputError(what, "missing field 'axis'");
    const auto a = JsonNumbers(g, "axis", -1, what);
    if (a.size() != 3) throw InputError(what, "axis must have 3 numbers");
    const Vec3 axis(a[0], a[1], a[2]);
    if (axis.norm() < 1e-9) throw InputError(what, "axis is zero");
    GyroErrorModel m = base;
    ApplyErrorModel(g, &m, what, true);
    u.axes_body.push_back(axis.normalized());
    u.gyros.push_back(m);
  }
  u.Check(file);
  return u;
}

Json GyroUnitToJson(const GyroUnit& unit) {
  Json gyros = Json::array();
  for (int i = 0; i < unit.size(); ++i) {
    const auto& m = unit.gyros[i];
    const Vec3& a = unit.axes_body[i];
    gyros.push_back({{"axis", {a.x(), a.y(), a.z()}},
                     {"bias_dph", m.bias_dph},
                     {"arw_deg_per_sqrt_h", m.arw_deg_per_sqrt_h},
                     {"bias_instability_dph", m.bias_instability_dph},
                     {"bias_instability_tau_s", m.bias_instability_tau_s},
                     {"rrw_dph_per_sqrt_h", m.rrw_dph_per_sqrt_h},
                     {"quantization_arcsec", m.quantization_arcsec},
                     {"scale_factor_ppm", m.scale_factor_ppm},
                     {"scale_factor_nonlinearity_ppm_per_dps", m.scale_factor_nonlinearity_ppm_per_dps},
                     {"scale_factor_asymmetry_ppm", m.scale_factor_asymmetry_ppm},
                     {"misalignment_arcsec", {m.misalignment_arcsec[0], m.misalignment_arcsec[1]}},
                     {"time_delay_s", m.time_delay_s},
                     {"thermal_k_dph", m.thermal.k_dph},
                     {"thermal_t0_c", m.thermal.t0_c},
                     {"thermal_t1_c", m.thermal.t1_c},
                     {"thermal_g0_c_per_min", m.thermal.g0_c_per_min},
                     {"magnetic_dph_per_ut",
                      {m.magnetic.along_dph_per_ut, m.magnetic.across_dph_per_ut, m.magnetic.vertical_dph_per_ut}}});
  }
  Json j = {{"rate_hz", unit.rate_hz}, {"gyros", gyros}};
  if (unit.calibrated) j["calibrated"] = true;
  return j;
}

GyroUnit LoadGyroUnit(const std::string& path) { return GyroUnitFromJson(ReadJsonFile(path), path); }

RateSolver::RateSolver(const GyroAxes& axes, const GyroVec& sigma, const std::vector<bool>& use) {
  if (!Make(axes, sigma, use, this)) throw InputError("unit", "the gyros in use do not span 3-D");
}

bool RateSolver::Make(const GyroAxes& axes, const GyroVec& sigma, const std::vector<bool>& use, RateSolver* out) {
  const int n = static_cast<int>(axes.rows());
  Mat3 info = Mat3::Zero();
  for (int i = 0; i < n; ++i) {
    if (!use[i]) continue;
    info += axes.row(i).transpose() * axes.row(i) / (sigma[i] * sigma[i]);
  }
  Eigen::SelfAdjointEigenSolver<Mat3> eig(info);
  if (!(eig.eigenvalues()(0) > 1e-9 * eig.eigenvalues()(2))) return false;
  out->cov_ = info.inverse();
  out->pinv_ = GyroPinv::Zero(3, n);
  for (int i = 0; i < n; ++i) {
    if (use[i]) out->pinv_.col(i) = out->cov_ * axes.row(i).transpose() / (sigma[i] * sigma[i]);
  }
  return true;
}

GyroParity ParityMatrix(const GyroAxes& axes, const std::vector<bool>& use) {
  const int n = static_cast<int>(axes.rows());
  // Fixed-capacity storage: called again when a gyro is isolated, on the per-sample path.
  int idx[kMaxGyros];
  int m = 0;
  for (int i = 0; i < n; ++i) {
    if (use[i]) idx[m++] = i;
  }
  GyroParity v = GyroParity::Zero(std::max(m - 3, 0), n);
  if (m <= 3) return v;
  GyroAxes hs(m, 3);
  for (int r = 0; r < m; ++r) hs.row(r) = axes.row(idx[r]);
  // H_s = Q R (Householder): H_s's columns lie in the span of Q's first three, so Q's last m - 3 columns
  // are orthonormal and orthogonal to every column of H_s, its left null space (even where H_s has lost
  // rank). With four gyros that space is one line, the same vector as any other method's up to the sign
  // fixed below; with five or six its basis is one of many, and every use of V goes through the
  // parity covariance V S V^T (fdi.cc, unit_calibrator.cc), whose statistics do not depend on it.
  const Eigen::HouseholderQR<GyroAxes> qr(hs);
  const GyroParity q = qr.householderQ();
  const GyroParity null = q.rightCols(m - 3);
  for (int k = 0; k < m - 3; ++k) {
    // Sign convention: the last used gyro's entry is negative (gives the four-FOG unit the familiar
    // p = (g1 + g2 + g3)/sqrt(6) - g4/sqrt(2)).
    const double sign = null(m - 1, k) > 0 ? -1.0 : 1.0;
    for (int r = 0; r < m; ++r) v(k, idx[r]) = sign * null(r, k);
  }
  return v;
}

}  // namespace ssiu
