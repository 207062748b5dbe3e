// The pixel fits of a solution's matches: Gauss-Newton on the centroids' residuals over the attitude,
// the focal length's scale and the principal point, the F-tests that decide whether a fixed camera's
// focal length and principal point stand (docs/identify.md, "Focal length"), and the retests made on a
// solved identification (RetestFocalLength, RetestPrincipalPoint, FittedCamera).
#include <algorithm>
#include <cmath>
#include <vector>

#include "identify/identify.h"
#include "identify/identify_internal.h"

namespace ssiu {
namespace identify_internal {

// The pixel fit (PixelFit) of the matches, in *fit.
const PixelFit& LinearizeInto(const ScratchVec<StarMatch>& ms, const Camera& cam, const Mat3& r, PixelSigma sigma,
                              PixelFit* fit) {
  PixelFit& f = *fit;
  f.j.clear();
  f.e.clear();
  f.w.clear();
  f.ok.clear();
  f.h.setZero();
  f.g.setZero();
  auto residual = [&](const StarMatch& m, const Vec4& x, Vec2* out) {
    Camera c2 = cam;
    c2.ScaleFocal(1 + x[3]);
    const auto p = c2.Project((r * ExpSo3(x.head<3>())).transpose() * m.r_inertial);
    if (!p) return false;
    *out = Vec2(m.x_px, m.y_px) - *p;
    return true;
  };
  for (const auto& m : ms) {
    Vec2 e0 = Vec2::Zero();
    Eigen::Matrix<double, 2, 4> j = Eigen::Matrix<double, 2, 4>::Zero();
    const bool ok = residual(m, Vec4::Zero(), &e0);
    if (ok) {
      for (int k = 0; k < 4; ++k) {
        Vec4 dx = Vec4::Zero();
        dx[k] = 1e-7;
        Vec2 e1;
        if (!residual(m, dx, &e1)) e1 = e0;
        j.col(k) = -(e1 - e0) / 1e-7;  // of the prediction
      }
    }
    const double w = ok ? 1.0 / std::pow(sigma.Of(m), 2) : 0.0;
    f.j.push_back(j);
    f.e.push_back(e0);
    f.w.push_back(w);
    f.ok.push_back(ok);
    f.h += w * j.transpose() * j;
    f.g += w * j.transpose() * e0;
  }
  return f;
}

// Gauss-Newton on pixel residuals over a small rotation (sensor frame), and with fit_scale a common
// scale of fx and fy (the pixel aspect fy/fx is the camera's); 4 iterations at most.
void PixelGaussNewton(const ScratchVec<StarMatch>& ms, PixelSigma sigma, PixelFit* fit, bool fit_scale, Camera* cam,
                      Mat3* r) {
  for (int iter = 0; iter < 4; ++iter) {
    const PixelFit& f = LinearizeInto(ms, *cam, *r, sigma, fit);
    Vec4 dx = Vec4::Zero();
    if (fit_scale)
      dx = f.h.ldlt().solve(f.g);
    else
      dx.head<3>() = f.h.topLeftCorner<3, 3>().ldlt().solve(f.g.head<3>());
    if (!dx.allFinite()) return;
    cam->ScaleFocal(1 + dx[3]);
    *r = *r * ExpSo3(dx.head<3>());
    if (dx.head<3>().norm() < 1e-10 && std::abs(dx[3]) < 1e-10) break;
  }
}

// PixelGaussNewton, then the fit's chi-square (centroid sigmas) at its end.
double PixelChi2(const ScratchVec<StarMatch>& ms, PixelSigma sigma, PixelFit* fit, bool fit_scale, Camera* cam,
                 Mat3* r) {
  PixelGaussNewton(ms, sigma, fit, fit_scale, cam, r);
  const PixelFit& f = LinearizeInto(ms, *cam, *r, sigma, fit);
  double chi2 = 0;
  for (size_t i = 0; i < f.e.size(); ++i) chi2 += f.w[i] * f.e[i].squaredNorm();
  return chi2;
}

// Two-sided tail P(|T| >= t) of Student's t with nu degrees of freedom (integer nu >= 1), by the finite
// series of Abramowitz & Stegun 26.7.3-26.7.4 for A(t|nu) = 1 - P: theta = atan(t / sqrt(nu)).
double StudentTwoSidedTail(double t, int nu) {
  if (!(t > 0) || nu < 1) return 1.0;
  const double th = std::atan(t / std::sqrt(static_cast<double>(nu)));
  const double c2 = std::cos(th) * std::cos(th), sn = std::sin(th);
  double a;
  if (nu % 2 == 1) {
    double term = std::cos(th), sum = nu > 1 ? term : 0.0;
    for (int k = 3; k <= nu - 2; k += 2) sum += (term *= c2 * (k - 1) / k);
    a = 2 / kPi * (th + sn * sum);
  } else {
    double term = 1, sum = 1;
    for (int k = 2; k <= nu - 2; k += 2) sum += (term *= c2 * (k - 1) / k);
    a = sn * sum;
  }
  return std::clamp(1 - a, 0.0, 1.0);
}

// Whether the matches ask for another focal length than the camera's (a fixed-focal solve, issue 27):
// the pixel fit with the rotation alone against the rotation and a common scale of fx and fy, by the
// F-test of the extra parameter, F = (chi2_0 - chi2_1) / (chi2_1 / nu), nu = 2n - 4, which does not
// depend on the centroid sigmas' scale (a camera whose distortion is unmodelled inflates every
// residual alike). F(1, nu) is t(nu)^2, so p = P(|T| >= sqrt(F)). The scale fit is left in *cam, *r.
double ScaleFitP(const ScratchVec<StarMatch>& ms, PixelSigma sigma, PixelFit* fit, Camera* cam, Mat3* r) {
  const int n = static_cast<int>(ms.size());
  Camera c0 = *cam;
  Mat3 r0 = *r;
  const double chi2_0 = PixelChi2(ms, sigma, fit, false, &c0, &r0);
  const double chi2_1 = PixelChi2(ms, sigma, fit, true, cam, r);
  const int nu = 2 * n - 4;
  if (nu < 1 || !(chi2_1 > 0) || !(chi2_0 > chi2_1)) return 1.0;
  return StudentTwoSidedTail(std::sqrt((chi2_0 - chi2_1) / (chi2_1 / nu)), nu);
}

// Whether the matches lie across the field: at least 2 in each quadrant about the principal point (a
// principal point is told from a turn of the attitude only by the perspective of stars on all sides).
bool AcrossTheField(const ScratchVec<StarMatch>& ms, const Camera& cam) {
  int q[4] = {0, 0, 0, 0};
  for (const auto& m : ms) ++q[(m.x_px >= cam.cx_px ? 1 : 0) + (m.y_px >= cam.cy_px ? 2 : 0)];
  return *std::min_element(q, q + 4) >= 2;
}

// The F-test of the principal point: Gauss-Newton on pixel residuals over [rotation, (scale when
// fit_scale), cx, cy] against the fit without (cx, cy); F = (drop / 2) / (chi2_1 / nu) with
// nu = 2n - k, whose tail for 2 numerator degrees of freedom is (1 + 2F/nu)^(-nu/2) (Abramowitz &
// Stegun 26.6.4 with nu1 = 2). On success *cam and *r are the wider fit's, *sigma_px its (cx, cy)
// 1-sigma and *attitude_cov_rad2 what (cx, cy) add to the attitude's covariance (sensor axes): the
// joint fit's attitude block less the one with (cx, cy) held, a Schur complement, so positive
// semi-definite. A shift of the principal point is nearly a rotation about the cross-boresight axes
// (a pixel is 1/f rad), which only the perspective of a wide field tells apart: this term is most
// of the cross-boresight uncertainty after a refit. 1 when the wider fit does not lower chi2.
double PrincipalPointP(const ScratchVec<StarMatch>& ms, PixelSigma sigma, bool fit_scale, Camera* cam, Mat3* r,
                       Vec2* sigma_px, Mat3* attitude_cov_rad2) {
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  PixelFit fit;
  Camera c0 = *cam;
  Mat3 r0 = *r;
  const double chi2_0 = PixelChi2(ms, sigma, &fit, fit_scale, &c0, &r0);
  const int k = fit_scale ? 6 : 5;
  auto residual = [&](const StarMatch& m, const Camera& c, const Mat3& rot, const Vec6& x, Vec2* out) {
    Camera c2 = c;
    c2.ScaleFocal(1 + x[3]);
    c2.cx_px += x[4], c2.cy_px += x[5];
    const auto p = c2.Project((rot * ExpSo3(x.head<3>())).transpose() * m.r_inertial);
    if (!p) return false;
    *out = Vec2(m.x_px, m.y_px) - *p;
    return true;
  };
  const double step[6] = {1e-7, 1e-7, 1e-7, 1e-7, 1e-4, 1e-4};
  Camera c = c0;
  Mat3 rot = r0;
  Mat6 h;
  double chi2_1 = 0;
  for (int iter = 0; iter <= 5; ++iter) {
    h.setZero();
    Vec6 g = Vec6::Zero();
    chi2_1 = 0;
    for (const auto& m : ms) {
      Vec2 e0;
      if (!residual(m, c, rot, Vec6::Zero(), &e0)) continue;
      Eigen::Matrix<double, 2, 6> j;
      for (int q = 0; q < 6; ++q) {
        Vec6 dx = Vec6::Zero();
        dx[q] = step[q];
        Vec2 e1;
        if (!residual(m, c, rot, dx, &e1)) e1 = e0;
        j.col(q) = -(e1 - e0) / step[q];
      }
      const double w = 1.0 / std::pow(sigma.Of(m), 2);
      h += w * j.transpose() * j;
      g += w * j.transpose() * e0;
      chi2_1 += w * e0.squaredNorm();
    }
    if (!fit_scale) h.row(3).setZero(), h.col(3).setZero(), h(3, 3) = 1, g[3] = 0;
    if (iter == 5) break;  // the last pass only evaluates
    const Vec6 dx = h.ldlt().solve(g);
    if (!dx.allFinite()) return 1.0;
    c.ScaleFocal(1 + dx[3]);
    c.cx_px += dx[4], c.cy_px += dx[5];
    rot = rot * ExpSo3(dx.head<3>());
  }
  const int nu = 2 * static_cast<int>(ms.size()) - k;
  if (nu < 1 || !(chi2_1 > 0) || !(chi2_0 > chi2_1)) return 1.0;
  const Mat6 cov = h.ldlt().solve(Mat6::Identity());
  *sigma_px = Vec2(std::sqrt(std::max(0.0, cov(4, 4))), std::sqrt(std::max(0.0, cov(5, 5))));
  const Eigen::Matrix4d held = h.topLeftCorner<4, 4>().ldlt().solve(Eigen::Matrix4d::Identity());
  *attitude_cov_rad2 = cov.topLeftCorner<3, 3>() - held.topLeftCorner<3, 3>();
  *cam = c, *r = rot;
  const double f = ((chi2_0 - chi2_1) / 2) / (chi2_1 / nu);
  return std::pow(1 + 2 * f / nu, -0.5 * nu);
}

}  // namespace identify_internal

using namespace identify_internal;  // NOLINT: the stage's own helpers

// A refit camera and attitude made the solution's: the matches' sensor directions, sigmas and
// residuals, and the attitude.
static void UseCameraFit(const Camera& cam, const Mat3& r, PixelSigma sigma, Identification* id) {
  for (auto& m : id->matches) {
    m.b_sensor = cam.Unproject(Vec2(m.x_px, m.y_px));
    m.sigma_rad = sigma.Of(m) / cam.FocalMeanPx();
    m.residual_rad = Angle(r * m.b_sensor, m.r_inertial);
  }
  id->q_inertial_from_sensor = Quat(r).normalized();
  if (id->q_inertial_from_sensor.w() < 0) id->q_inertial_from_sensor.coeffs() *= -1;
}

void RetestFocalLength(const Camera& camera, const IdentifyOptions& o, Identification* id) {
  if (id->status != SolveStatus::kSolved || o.FocalSearched() || !(o.refine_focal_p > 0)) return;
  ScratchVec<StarMatch>& ms = id->matches;
  const PixelSigma sigma{nullptr, FittedCamera(camera, *id).FocalMeanPx()};  // what sigma_rad was made with
  Camera cam = camera;
  Mat3 r = id->q_inertial_from_sensor.toRotationMatrix();
  PixelFit fit;
  double p = std::nan("");
  bool refit = false;
  if (static_cast<int>(ms.size()) >= o.refine_focal_min_matches) {
    p = ScaleFitP(ms, sigma, &fit, &cam, &r);
    refit = p < o.refine_focal_p;
  }
  if (!refit) {
    cam = camera;
    r = id->q_inertial_from_sensor.toRotationMatrix();
    PixelGaussNewton(ms, sigma, &fit, false, &cam, &r);
  }
  id->focal_length_px = cam.focal_length_px;
  id->focal_length_y_px = cam.FocalYPx();
  id->focal_length_fitted = id->focal_length_refined = refit;
  id->focal_length_p_value = p;
  id->focal_length_sigma_px = 0;
  if (refit) {
    const double var = LinearizeInto(ms, cam, r, sigma, &fit).h.ldlt().solve(Vec4::UnitW())[3];
    id->focal_length_sigma_px = var > 0 ? std::sqrt(var) * cam.focal_length_px : std::nan("");
  }
  UseCameraFit(cam, r, sigma, id);
}

void RetestPrincipalPoint(const Camera& camera, const IdentifyOptions& o, Identification* id) {
  id->principal_point_refined = false;
  id->principal_point_attitude_cov_rad2.setZero();
  id->cx_px = id->cy_px = id->principal_point_sigma_px = id->principal_point_p_value = std::nan("");
  ScratchVec<StarMatch>& ms = id->matches;
  if (id->status != SolveStatus::kSolved || o.FocalSearched() || !(o.refine_focal_p > 0) ||
      !(o.refine_principal_p > 0) || static_cast<int>(ms.size()) < o.refine_principal_min_matches)
    return;
  Camera cam = FittedCamera(camera, *id);
  if (!AcrossTheField(ms, cam)) return;
  const PixelSigma sigma{nullptr, cam.FocalMeanPx()};  // what sigma_rad was made with
  Mat3 r = id->q_inertial_from_sensor.toRotationMatrix();
  Vec2 sigma_px = Vec2::Zero();
  Mat3 attitude_cov = Mat3::Zero();
  id->principal_point_p_value =
      PrincipalPointP(ms, sigma, id->focal_length_refined, &cam, &r, &sigma_px, &attitude_cov);
  if (!(id->principal_point_p_value < o.refine_principal_p)) return;
  id->principal_point_refined = true;
  id->principal_point_attitude_cov_rad2 = 0.5 * (attitude_cov + attitude_cov.transpose());
  id->cx_px = cam.cx_px, id->cy_px = cam.cy_px;
  id->principal_point_sigma_px = std::hypot(sigma_px[0], sigma_px[1]);
  id->focal_length_px = cam.focal_length_px;
  id->focal_length_y_px = cam.FocalYPx();
  UseCameraFit(cam, r, sigma, id);
}

Camera FittedCamera(Camera camera, const Identification& id) {
  if (id.focal_length_px > 0 && std::isfinite(id.focal_length_px))
    camera.ScaleFocal(id.focal_length_px / camera.focal_length_px);
  if (id.principal_point_refined) camera.cx_px = id.cx_px, camera.cy_px = id.cy_px;
  return camera;
}

}  // namespace ssiu
