// Helpers the identification's files share (not part of the stage's interface): the pixel fits of
// a solution's matches (camera_fit.cc: the focal length's and the principal point's tests) and the
// photometric tests (photometry.cc). See docs/identify.md, steps 5-6 and "Focal length".
#pragma once

#include <cstddef>
#include <utility>
#include <vector>

#include "core/types.h"
#include "identify/identify.h"

namespace ssiu::identify_internal {

inline double Angle(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

inline Mat3 ExpSo3(const Vec3& w) {
  const double t = w.norm();
  if (t < 1e-12) return Mat3::Identity();
  return Eigen::AngleAxisd(t, w / t).toRotationMatrix();
}

// Pixel residuals (centroid - prediction) of the matches under (cam, r) and their Jacobians over
// x = (small rotation in the sensor frame, r -> r Exp(x[0..2]); common scale of fx and fy, 1 + x[3]),
// numerical, with the weights 1 / sigma_px^2 and the normal equations H = sum w J^T J, g = sum w J^T e.
struct PixelFit {
  explicit PixelFit(std::pmr::memory_resource* mr = std::pmr::get_default_resource()) : j(mr), e(mr), w(mr), ok(mr) {}
  ScratchVec<Eigen::Matrix<double, 2, 4>> j;
  ScratchVec<Vec2> e;
  ScratchVec<double> w;
  ScratchVec<char> ok;  // projected (a star behind the camera has no residual)
  Eigen::Matrix4d h = Eigen::Matrix4d::Zero();
  Vec4 g = Vec4::Zero();
};

// Each match's position sigma (px): the workspace's by centroid, or from the match's own sigma_rad.
struct PixelSigma {
  const double* by_centroid = nullptr;
  double focal_px = 0;  // with by_centroid null: sigma_rad * focal_px
  double Of(const StarMatch& m) const { return by_centroid ? by_centroid[m.centroid] : m.sigma_rad * focal_px; }
};

// The pixel fit (PixelFit) of the matches under (cam, r), in *fit.
const PixelFit& LinearizeInto(const ScratchVec<StarMatch>& ms, const Camera& cam, const Mat3& r, PixelSigma sigma,
                              PixelFit* fit);
// Gauss-Newton on pixel residuals over a small rotation, and with fit_scale the common scale of fx, fy.
void PixelGaussNewton(const ScratchVec<StarMatch>& ms, PixelSigma sigma, PixelFit* fit, bool fit_scale, Camera* cam,
                      Mat3* r);
// PixelGaussNewton, then the fit's chi-square at its end.
double PixelChi2(const ScratchVec<StarMatch>& ms, PixelSigma sigma, PixelFit* fit, bool fit_scale, Camera* cam,
                 Mat3* r);
// Two-sided tail of Student's t with nu degrees of freedom.
double StudentTwoSidedTail(double t, int nu);
// The focal length's F-test p-value; the scale fit left in *cam, *r.
double ScaleFitP(const ScratchVec<StarMatch>& ms, PixelSigma sigma, PixelFit* fit, Camera* cam, Mat3* r);
// At least 2 matches in each quadrant about the principal point.
bool AcrossTheField(const ScratchVec<StarMatch>& ms, const Camera& cam);
// The principal point's F-test p-value; on success the wider fit in *cam, *r and its (cx, cy) sigmas.
double PrincipalPointP(const ScratchVec<StarMatch>& ms, PixelSigma sigma, bool fit_scale, Camera* cam, Mat3* r,
                       Vec2* sigma_px, Mat3* attitude_cov_rad2);

// The harmonic number H_T.
double Harmonic(double t);
// The triangle's photometric p-value and T (the triples it is ranked among).
std::pair<double, double> TriangleZeroPointP(const double* pair_flux, const double* pair_mag,
                                             const ScratchVec<double>& ln_brighter);
// The photometric evidence over n pairs and n_other other fluxes (scratch vectors for the zero points).
double PhotometricEvidenceOf(const double* pair_flux, const double* pair_mag, size_t n, const double* other_flux,
                             size_t n_other, ScratchVec<double>* zp, ScratchVec<double>* z);

}  // namespace ssiu::identify_internal
