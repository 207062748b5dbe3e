#include "calibration/fog_magnetic.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <set>

#include "core/csv.h"
#include "core/error.h"
#include "core/types.h"
#include "sim/fog_bench_sim.h"

namespace ssiu {
namespace {

using Vec4d = Eigen::Matrix<double, 4, 1>;
using Mat4d = Eigen::Matrix<double, 4, 4>;

// Generalised least squares fit f = dw + e1 cos(psi) + e2 sin(psi) over the dwell means: the
// covariance is the white part of each dwell mean (var_white) plus the Gauss-Markov wander,
// wander^2 exp(-|t_i - t_j|/tau). If the residuals scatter more than that model allows
// (chi^2/dof > 1), the covariance is scaled up by chi^2/dof.
struct LinearFit {
  Eigen::Vector3d beta;
  Eigen::Matrix3d cov;
  double rms = 0, inflation = 1;
};

LinearFit FitHarmonic(const std::vector<double>& psi_rad, const std::vector<double>& f,
                      const std::vector<double>& t_mid_s, const std::vector<double>& var_white, double wander_sigma,
                      double wander_tau_s) {
  const int n = static_cast<int>(f.size());
  Eigen::MatrixXd a(n, 3), sigma(n, n);
  Eigen::VectorXd y(n);
  for (int i = 0; i < n; ++i) {
    a(i, 0) = 1;
    a(i, 1) = std::cos(psi_rad[i]);
    a(i, 2) = std::sin(psi_rad[i]);
    y(i) = f[i];
    for (int j = 0; j < n; ++j) {
      sigma(i, j) = wander_sigma * wander_sigma * std::exp(-std::abs(t_mid_s[i] - t_mid_s[j]) / wander_tau_s);
    }
    sigma(i, i) += std::max(var_white[i], 1e-12);
  }
  const Eigen::LLT<Eigen::MatrixXd> llt(sigma);
  const Eigen::MatrixXd aw = llt.matrixL().solve(a);
  const Eigen::VectorXd yw = llt.matrixL().solve(y);
  const Eigen::Matrix3d ata = aw.transpose() * aw;
  LinearFit fit;
  fit.beta = ata.ldlt().solve(aw.transpose() * yw);
  const double chi2_dof = (yw - aw * fit.beta).squaredNorm() / std::max(1, n - 3);
  fit.inflation = std::max(1.0, chi2_dof);
  fit.cov = fit.inflation * ata.inverse();
  fit.rms = std::sqrt((y - a * fit.beta).squaredNorm() / n);
  return fit;
}

// Quantities derived from theta = (E_x1, E_x2, E_y1, E_y2); see the header.
struct Derived {
  double dpsi0_rad, scale, c, d, measure, amp_x, amp_y, hx1, hx2, hy1, hy2;
};

Derived Derive(const Vec4d& th, double w) {
  Derived r;
  const double a = 0.5 * (th(0) + th(3)), b = 0.5 * (th(2) - th(1));
  r.dpsi0_rad = std::atan2(b, w + a);
  r.scale = std::hypot(w + a, b) - w;
  r.c = 0.5 * (th(0) - th(3));
  r.d = 0.5 * (th(1) + th(2));
  r.measure = std::hypot(r.c, r.d);
  // Trim alone: f_x = W(cos d - 1) cos psi - W sin d sin psi, f_y = W sin d cos psi + W(cos d - 1) sin psi.
  const double cd = std::cos(r.dpsi0_rad) - 1, sd = std::sin(r.dpsi0_rad);
  r.hx1 = th(0) - w * cd;
  r.hx2 = th(1) + w * sd;
  r.hy1 = th(2) - w * sd;
  r.hy2 = th(3) - w * cd;
  r.amp_x = std::hypot(r.hx1, r.hx2);
  r.amp_y = std::hypot(r.hy1, r.hy2);
  return r;
}

// Sigma of g(theta) by first-order propagation with a central-difference gradient.
double Sigma(const std::function<double(const Vec4d&)>& g, const Vec4d& th, const Mat4d& cov) {
  Vec4d grad;
  for (int k = 0; k < 4; ++k) {
    const double h = 1e-6 * std::max(1.0, std::abs(th(k)));
    Vec4d p = th, m = th;
    p(k) += h;
    m(k) -= h;
    grad(k) = (g(p) - g(m)) / (2 * h);
  }
  return std::sqrt(std::max(0.0, grad.dot(cov * grad)));
}

// Amplitude and phase of e1 cos + e2 sin as S sin(psi + phi) (x) or S cos(psi + phi) (y), the
// phase folded into +-90 deg (the sign goes to S), with propagated sigmas.
void AmplitudePhase(bool x_axis, const LinearFit& f, AxisHarmonicFit* out) {
  const double e1 = f.beta(1), e2 = f.beta(2);
  out->dw_dph = f.beta(0);
  out->dw_sigma_dph = std::sqrt(f.cov(0, 0));
  out->e_cos_dph = e1;
  out->e_sin_dph = e2;
  out->residual_rms_dph = f.rms;
  out->variance_inflation = f.inflation;
  double phi = x_axis ? std::atan2(e1, e2) : std::atan2(-e2, e1), s = std::hypot(e1, e2);
  if (phi > kPi / 2) {
    phi -= kPi;
    s = -s;
  } else if (phi < -kPi / 2) {
    phi += kPi;
    s = -s;
  }
  out->s_dph = s;
  out->phi_deg = phi * kRadToDeg;
  const Eigen::Matrix2d c = f.cov.bottomRightCorner<2, 2>();
  const double r = std::hypot(e1, e2);
  if (r > 0) {
    const Eigen::Vector2d gs(e1 / r, e2 / r);
    const Eigen::Vector2d gp = Eigen::Vector2d(e2, -e1) / (r * r);  // same for both phase forms
    out->s_sigma_dph = std::sqrt(gs.dot(c * gs));
    out->phi_sigma_deg = std::sqrt(gp.dot(c * gp)) * kRadToDeg;
  }
}

}  // namespace

void MagneticOptions::Check() const {
  if (!(latitude_deg > -90 && latitude_deg < 90)) throw InputError("--latitude-deg", "must be within (-90, 90)");
  if (!(settle_s >= 0) || !(min_dwell_s > 0) || !(azimuth_tol_deg > 0)) {
    throw InputError("options", "settle_s, min_dwell_s and azimuth_tol_deg must be positive");
  }
  if (min_positions < 4) throw InputError("options", "min_positions must be >= 4");
  if (!(wander_sigma_dph >= 0) || !(wander_tau_s > 0)) throw InputError("options", "bad wander sigma or tau");
}

TurntableData ReadTurntableLog(const std::string& path) {
  const CsvTable csv = ReadCsv(path);
  TurntableData d;
  d.file = path;
  d.t_s = csv.Column("t_s");
  d.wx_dph = csv.Column("wx_dph");
  d.wy_dph = csv.Column("wy_dph");
  d.azimuth_deg = csv.Column("azimuth_deg");
  csv.CheckIncreasing("t_s");
  return d;
}

MagneticResult FitMagneticSensitivity(const TurntableData& log, const MagneticOptions& o) {
  o.Check();
  const size_t n = log.t_s.size();
  if (log.wx_dph.size() != n || log.wy_dph.size() != n || log.azimuth_deg.size() != n) {
    throw InputError(log.file, "columns of different length");
  }
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(log.t_s[i]) || !std::isfinite(log.wx_dph[i]) || !std::isfinite(log.wy_dph[i]) ||
        !std::isfinite(log.azimuth_deg[i])) {
      throw InputError(log.file, "row " + std::to_string(i + 1) + ": not a finite number");
    }
    if (i > 0 && !(log.t_s[i] > log.t_s[i - 1])) {
      throw InputError(log.file, "column 't_s' is not strictly increasing at row " + std::to_string(i + 1));
    }
  }
  MagneticResult res;
  res.status = FitStatus::kFitted;
  res.file = log.file;
  res.w_phi_dph = kEarthRateDph * std::cos(o.latitude_deg * kDegToRad);

  // Dwell segments: maximal runs at a constant azimuth; the first settle_s of each is dropped.
  size_t start = 0;
  for (size_t i = 1; i <= n; ++i) {
    if (i < n && std::abs(log.azimuth_deg[i] - log.azimuth_deg[start]) <= o.azimuth_tol_deg) continue;
    DwellMean d;
    double sx = 0, sy = 0, sxx = 0, syy = 0;
    for (size_t k = start; k < i; ++k) {
      if (log.t_s[k] - log.t_s[start] < o.settle_s) continue;
      if (d.samples == 0) d.t_start_s = log.t_s[k];
      d.t_end_s = log.t_s[k];
      sx += log.wx_dph[k];
      sy += log.wy_dph[k];
      sxx += log.wx_dph[k] * log.wx_dph[k];
      syy += log.wy_dph[k] * log.wy_dph[k];
      ++d.samples;
    }
    if (d.samples >= 2 && d.t_end_s - d.t_start_s >= o.min_dwell_s) {
      d.azimuth_deg = log.azimuth_deg[start];
      d.wx_dph = sx / d.samples;
      d.wy_dph = sy / d.samples;
      // Variance of the mean from the scatter within the dwell (white part).
      d.var_mean_x = std::max(0.0, sxx / d.samples - d.wx_dph * d.wx_dph) / (d.samples - 1);
      d.var_mean_y = std::max(0.0, syy / d.samples - d.wy_dph * d.wy_dph) / (d.samples - 1);
      res.dwells.push_back(d);
    }
    start = i;
  }
  std::set<long> distinct;
  for (const auto& d : res.dwells) {
    double a = std::fmod(d.azimuth_deg, 360.0);
    if (a < 0) a += 360;
    distinct.insert(std::lround(a * 10) % 3600);
  }
  if (static_cast<int>(distinct.size()) < o.min_positions) {
    throw InputError(log.file, "too few azimuths: " + std::to_string(distinct.size()) +
                                   " distinct dwell positions (>= " + std::to_string(o.min_dwell_s) +
                                   " s after settling), need >= " + std::to_string(o.min_positions));
  }

  std::vector<double> psi, fx, fy, tm, vx, vy;
  for (const auto& d : res.dwells) {
    const double p = d.azimuth_deg * kDegToRad;
    psi.push_back(p);
    tm.push_back(0.5 * (d.t_start_s + d.t_end_s));
    vx.push_back(d.var_mean_x);
    vy.push_back(d.var_mean_y);
    fx.push_back(d.wx_dph - res.w_phi_dph * std::cos(p));  // eq. (2) minus the nominal Earth rate
    fy.push_back(d.wy_dph - res.w_phi_dph * std::sin(p));  // eq. (3)
  }
  const LinearFit lx = FitHarmonic(psi, fx, tm, vx, o.wander_sigma_dph, o.wander_tau_s);
  const LinearFit ly = FitHarmonic(psi, fy, tm, vy, o.wander_sigma_dph, o.wander_tau_s);
  AmplitudePhase(true, lx, &res.x);
  AmplitudePhase(false, ly, &res.y);

  const Vec4d th(lx.beta(1), lx.beta(2), ly.beta(1), ly.beta(2));
  Mat4d cov = Mat4d::Zero();
  cov.topLeftCorner<2, 2>() = lx.cov.bottomRightCorner<2, 2>();
  cov.bottomRightCorner<2, 2>() = ly.cov.bottomRightCorner<2, 2>();
  const double w = res.w_phi_dph;
  const Derived dv = Derive(th, w);
  res.dpsi0_deg = dv.dpsi0_rad * kRadToDeg;
  res.dpsi0_sigma_deg = Sigma([w](const Vec4d& t) { return Derive(t, w).dpsi0_rad; }, th, cov) * kRadToDeg;
  res.scale_departure_dph = dv.scale;
  res.scale_departure_sigma_dph = Sigma([w](const Vec4d& t) { return Derive(t, w).scale; }, th, cov);
  res.anticonformal_c_dph = dv.c;
  res.anticonformal_d_dph = dv.d;
  res.magnetic_measure_dph = dv.measure;
  res.magnetic_measure_sigma_dph = Sigma([w](const Vec4d& t) { return Derive(t, w).measure; }, th, cov);
  res.magnetic_amplitude_x_dph = dv.amp_x;
  res.magnetic_amplitude_y_dph = dv.amp_y;
  const bool x_larger = dv.amp_x >= dv.amp_y;
  res.magnetic_amplitude_dph = std::max(dv.amp_x, dv.amp_y);
  res.magnetic_amplitude_sigma_dph = Sigma(
      [w, x_larger](const Vec4d& t) {
        const Derived q = Derive(t, w);
        return x_larger ? q.amp_x : q.amp_y;
      },
      th, cov);

  // Chi-square of the parts a trim error cannot make, (c, d, scale departure), against zero.
  Eigen::Matrix<double, 3, 4> j;
  for (int k = 0; k < 4; ++k) {
    const double h = 1e-6;
    Vec4d p = th, m = th;
    p(k) += h;
    m(k) -= h;
    const Derived dp = Derive(p, w), dm = Derive(m, w);
    j(0, k) = (dp.c - dm.c) / (2 * h);
    j(1, k) = (dp.d - dm.d) / (2 * h);
    j(2, k) = (dp.scale - dm.scale) / (2 * h);
  }
  const Eigen::Matrix3d cv = j * cov * j.transpose();
  const Eigen::Vector3d v(dv.c, dv.d, dv.scale);
  res.magnetic_chi2 = v.dot(cv.ldlt().solve(v));
  res.consistent_with_zero = res.magnetic_chi2 < 14.16;  // chi^2_3 at 99.73 % (3 sigma)
  return res;
}

MagneticCurves MagneticFitCurves(const MagneticResult& fit, int points) {
  MagneticCurves c;
  const Vec4d th(fit.x.e_cos_dph, fit.x.e_sin_dph, fit.y.e_cos_dph, fit.y.e_sin_dph);
  const Derived dv = Derive(th, fit.w_phi_dph);
  for (int i = 0; i < points; ++i) {
    const double deg = 360.0 * i / std::max(1, points - 1), p = deg * kDegToRad;
    c.psi_deg.push_back(deg);
    c.fx_dph.push_back(fit.x.dw_dph + fit.x.e_cos_dph * std::cos(p) + fit.x.e_sin_dph * std::sin(p));
    c.fy_dph.push_back(fit.y.dw_dph + fit.y.e_cos_dph * std::cos(p) + fit.y.e_sin_dph * std::sin(p));
    c.mag_x_dph.push_back(dv.hx1 * std::cos(p) + dv.hx2 * std::sin(p));
    c.mag_y_dph.push_back(dv.hy1 * std::cos(p) + dv.hy2 * std::sin(p));
  }
  return c;
}

Json MagneticResultToJson(const MagneticResult& f) {
  auto axis = [](const AxisHarmonicFit& a) {
    return Json{{"dW_dph", a.dw_dph},
                {"dW_sigma_dph", a.dw_sigma_dph},
                {"S_dph", a.s_dph},
                {"S_sigma_dph", a.s_sigma_dph},
                {"phi_deg", a.phi_deg},
                {"phi_sigma_deg", a.phi_sigma_deg},
                {"residual_rms_dph", a.residual_rms_dph},
                {"variance_inflation", a.variance_inflation}};
  };
  Json dw = Json::array();
  for (const auto& d : f.dwells) {
    dw.push_back({{"azimuth_deg", d.azimuth_deg},
                  {"t_start_s", d.t_start_s},
                  {"t_end_s", d.t_end_s},
                  {"wx_dph", d.wx_dph},
                  {"wy_dph", d.wy_dph},
                  {"samples", d.samples}});
  }
  return Json{{"status", FitStatusName(f.status)},
              {"file", f.file},
              {"w_phi_dph", f.w_phi_dph},
              {"x", axis(f.x)},
              {"y", axis(f.y)},
              {"dpsi0_deg", f.dpsi0_deg},
              {"dpsi0_sigma_deg", f.dpsi0_sigma_deg},
              {"magnetic_measure_dph", f.magnetic_measure_dph},
              {"magnetic_measure_sigma_dph", f.magnetic_measure_sigma_dph},
              {"anticonformal_c_dph", f.anticonformal_c_dph},
              {"anticonformal_d_dph", f.anticonformal_d_dph},
              {"scale_departure_dph", f.scale_departure_dph},
              {"scale_departure_sigma_dph", f.scale_departure_sigma_dph},
              {"magnetic_amplitude_dph", f.magnetic_amplitude_dph},
              {"magnetic_amplitude_sigma_dph", f.magnetic_amplitude_sigma_dph},
              {"magnetic_amplitude_x_dph", f.magnetic_amplitude_x_dph},
              {"magnetic_amplitude_y_dph", f.magnetic_amplitude_y_dph},
              {"magnetic_chi2", f.magnetic_chi2},
              {"magnetic_chi2_dof", 3},
              {"consistent_with_zero", f.consistent_with_zero},
              {"dwells", dw}};
}

}  // namespace ssiu
