// Fiducials (libapriltag) and the plate pose (OpenCV solvePnP) of reference.h, in the OpenCV edge
// module (core/opencv_edge.h).
#include <apriltag/apriltag.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/calib3d.hpp>
#include <set>

#include "core/attitude.h"
#include "core/csv.h"
#include "core/error.h"
#include "core/image.h"
#include "groundtest/apriltag_family.h"
#include "groundtest/reference.h"
#include "groundtest/tag_edges.h"

namespace ssiu {

std::vector<FiducialDetection> DetectFiducials(const uint8_t* pixels, int width, int height, const std::string& family,
                                               const FiducialOptions& o) {
  o.Check();
  auto fam = groundtest_internal::CreateFamily(family);
  if (!fam) throw InputError("tag family", "unknown '" + family + "'");
  apriltag_detector_t* td = apriltag_detector_create();
  apriltag_detector_add_family(td, fam.get());
  td->quad_decimate = static_cast<float>(o.quad_decimate);
  td->nthreads = 1;
  td->refine_edges = true;
  // A view of the caller's pixels (libapriltag reads, never writes, its input image).
  std::vector<uint8_t> buf(pixels, pixels + static_cast<size_t>(width) * height);
  image_u8_t im{width, height, width, buf.data()};
  zarray_t* dets = apriltag_detector_detect(td, &im);
  std::vector<FiducialDetection> out;
  for (int i = 0; i < zarray_size(dets); ++i) {
    apriltag_detection_t* d = nullptr;
    zarray_get(dets, i, &d);
    FiducialDetection f;
    f.id = d->id, f.hamming = d->hamming, f.decision_margin = d->decision_margin;
    // libapriltag puts pixel centres at +0.5 (its corner-of-pixel origin); ssiu at integers.
    for (int k = 0; k < 4; ++k) f.corners_px[k] = Vec2(d->p[k][0] - 0.5, d->p[k][1] - 0.5);
    out.push_back(f);
  }
  apriltag_detections_destroy(dets);
  apriltag_detector_destroy(td);
  std::sort(out.begin(), out.end(), [](const FiducialDetection& a, const FiducialDetection& b) { return a.id < b.id; });
  return out;
}

namespace {

// Corner accuracy assumed for a tag whose edges could not be fitted (libapriltag's own corners:
// pixel-phase errors of ~0.1 px, measured on simulated photos).
constexpr double kUnrefinedCornerSigmaPx = 0.1;

PlatePose PoseInC(const AuxCamera& aux, const Mat3& r_ap, const Vec3& t_ap) {
  PlatePose p;
  p.r_c_from_p = aux.r_aux_from_c.transpose() * r_ap;
  p.t_c_mm = aux.r_aux_from_c.transpose() * (t_ap - aux.t_aux_mm);
  return p;
}

Mat3 FromRvec(const Vec3& r) {
  const double a = r.norm();
  return a < 1e-15 ? Mat3::Identity() : Mat3(Eigen::AngleAxisd(a, r / a));
}

}  // namespace

PlatePoseEstimate EstimatePlatePose(const Mask& m, const AuxCamera& aux, const uint8_t* pixels, int width, int height,
                                    const std::string& photo, const FiducialOptions& o) {
  if (width != aux.camera.width || height != aux.camera.height)
    throw InputError(photo, "size " + std::to_string(width) + "x" + std::to_string(height) +
                                " differs from the aux camera's " + std::to_string(aux.camera.width) + "x" +
                                std::to_string(aux.camera.height));
  const std::vector<FiducialDetection> dets = DetectFiducials(pixels, width, height, m.tag_family, o);
  if (dets.empty()) {
    for (const auto& other : groundtest_internal::KnownFamilies()) {
      if (other == m.tag_family) continue;
      if (!DetectFiducials(pixels, width, height, other, o).empty())
        throw InputError(photo,
                         "shows " + other + " fiducials, but the mask uses " + m.tag_family + " (wrong tag family)");
    }
    throw InputError(photo, "no " + m.tag_family + " fiducials visible");
  }
  std::map<int, const MaskTag*> by_id;
  for (const auto& t : m.tags) by_id[t.id] = &t;
  auto fam = groundtest_internal::CreateFamily(m.tag_family);
  const int border_cells = static_cast<int>(fam->width_at_border);
  const Camera& c = aux.camera;
  std::vector<cv::Point3d> obj;
  std::vector<cv::Point2d> img;                      // undistorted (pinhole) pixel coordinates
  std::vector<Eigen::Matrix<double, 8, 8>> tag_cov;  // per unit pixel noise (refined) or absolute (not)
  std::vector<bool> refined;
  PlatePoseEstimate e;
  std::string foreign;
  double rss = 0;
  long dof_fit = 0;
  for (const auto& d : dets) {
    auto it = by_id.find(d.id);
    if (it == by_id.end()) {
      foreign += (foreign.empty() ? "" : ",") + std::to_string(d.id);
      continue;
    }
    groundtest_internal::TagCornerFit fit;
    if (o.refine_corners)
      fit = groundtest_internal::FitTagCorners(pixels, width, height, c, d.corners_px, border_cells);
    const auto corners = it->second->Corners();
    for (int k = 0; k < 4; ++k) {
      obj.emplace_back(corners[k].x(), corners[k].y(), 0.0);
      const Vec2 p = fit.ok ? fit.corners_px[k] : groundtest_internal::UndistortPixel(c, d.corners_px[k]);
      img.emplace_back(p.x(), p.y());
    }
    if (fit.ok) {
      rss += fit.rss_dn2, dof_fit += fit.pixels - fit.parameters;
      tag_cov.push_back(fit.covariance);
      ++e.refined_tags;
    } else {
      tag_cov.push_back(Eigen::Matrix<double, 8, 8>::Identity() * kUnrefinedCornerSigmaPx * kUnrefinedCornerSigmaPx);
    }
    refined.push_back(fit.ok);
    e.tag_ids.push_back(d.id);
  }
  if (static_cast<int>(e.tag_ids.size()) < o.min_tags)
    throw InputError(photo, std::to_string(e.tag_ids.size()) + " of this mask's " + m.tag_family +
                                " fiducials visible (need " + std::to_string(o.min_tags) + ")" +
                                (foreign.empty() ? "" : "; tags " + foreign + " belong to another mask"));
  // The photo's pixel noise: given, or measured from the edge fits' residuals.
  e.pixel_noise_dn = o.pixel_noise_dn > 0 ? o.pixel_noise_dn : (dof_fit > 0 ? std::sqrt(rss / dof_fit) : 0.0);
  e.measured_pixel_noise_dn = dof_fit > 0 ? std::sqrt(rss / dof_fit) : 0.0;
  const int nt = static_cast<int>(e.tag_ids.size());
  const int n_obs = 8 * nt;
  Eigen::MatrixXd Sigma = Eigen::MatrixXd::Zero(n_obs, n_obs);  // corner covariance, px^2
  for (int t = 0; t < nt; ++t)
    Sigma.block<8, 8>(8 * t, 8 * t) =
        refined[t] ? Eigen::Matrix<double, 8, 8>(tag_cov[t] * e.pixel_noise_dn * e.pixel_noise_dn) : tag_cov[t];
  e.predicted_corner_sigma_px = std::sqrt(Sigma.diagonal().mean());
  const cv::Matx33d K(c.focal_length_px, 0, c.cx_px, 0, c.FocalYPx(), c.cy_px, 0, 0, 1);
  const std::vector<double> dist;  // corners are undistorted already
  // Planar target: IPPE for the start, then Levenberg-Marquardt on all corners.
  cv::Mat rvec, tvec;
  if (!cv::solvePnP(obj, img, K, dist, rvec, tvec, false, cv::SOLVEPNP_IPPE))
    throw InputError(photo, "PnP pose of the fiducials failed");
  cv::solvePnPRefineLM(obj, img, K, dist, rvec, tvec);
  std::vector<cv::Point2d> proj;
  cv::Mat jac;
  cv::projectPoints(obj, rvec, tvec, K, dist, proj, jac);
  Eigen::VectorXd res(n_obs);
  for (size_t i = 0; i < img.size(); ++i) res(2 * i) = img[i].x - proj[i].x, res(2 * i + 1) = img[i].y - proj[i].y;
  e.rms_reprojection_px = std::sqrt(res.squaredNorm() / (n_obs / 2.0));
  e.corner_sigma_px = std::sqrt(res.squaredNorm() / std::max(1, n_obs - 6));
  Eigen::MatrixXd J(n_obs, 6);
  for (int r = 0; r < n_obs; ++r)
    for (int k = 0; k < 6; ++k) J(r, k) = jac.at<double>(r, k);
  // Unweighted least squares with correlated corner errors: covariance (J^T J)^-1 J^T Sigma J (J^T J)^-1.
  const Eigen::Matrix<double, 6, 6> JtJi = (J.transpose() * J).inverse();
  const Eigen::Matrix<double, 6, Eigen::Dynamic> A = JtJi * J.transpose();
  const Eigen::Matrix<double, 6, 6> noise_cov = A * Sigma * A.transpose();
  // Do the residuals agree with the predicted corner noise? chi2 of the residuals against Sigma
  // (Birge ratio); a larger scatter (a real photo's systematics) scales the covariance up.
  e.corner_chi2_per_dof = res.dot(Sigma.ldlt().solve(res)) / std::max(1, n_obs - 6);
  const double birge2 = std::max(1.0, e.corner_chi2_per_dof);
  e.covariance = noise_cov * birge2;
  const Vec3 rv(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2));
  const Vec3 tv(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
  e.r_aux_from_p = FromRvec(rv);
  e.t_aux_mm = tv;
  e.pose = PoseInC(aux, e.r_aux_from_p, e.t_aux_mm);
  e.q_c_from_m = MaskRotation(m, e.pose);
  // Numerical Jacobian of the mask rotation (rotation vector, C frame) w.r.t. the 6 PnP parameters.
  Eigen::Matrix<double, 3, 6> G;
  for (int k = 0; k < 6; ++k) {
    const double h = k < 3 ? 1e-6 : 1e-3;
    Vec3 r2 = rv, t2 = tv;
    if (k < 3)
      r2(k) += h;
    else
      t2(k - 3) += h;
    const Quat q2 = MaskRotation(m, PoseInC(aux, FromRvec(r2), t2));
    G.col(k) = RotationVector(q2 * e.q_c_from_m.conjugate()) / h;
  }
  e.q_c_from_m_noise_cov_rad2 = G * noise_cov * G.transpose();
  e.q_c_from_m_cov_rad2 = G * e.covariance * G.transpose();
  // A leave-one-tag-out jackknife (Efron & Stein 1981) sees errors the noise model misses (a real
  // photo's uneven lighting, a tag printed off its place); each axis takes the larger of the two
  // variances, keeping the formal correlations.
  if (nt >= 3) {
    std::vector<Vec3> d;
    for (int leave = 0; leave < nt; ++leave) {
      std::vector<cv::Point3d> o2;
      std::vector<cv::Point2d> i2;
      for (int k = 0; k < static_cast<int>(obj.size()); ++k)
        if (k / 4 != leave) o2.push_back(obj[k]), i2.push_back(img[k]);
      cv::Mat r2 = rvec.clone(), t2 = tvec.clone();
      cv::solvePnPRefineLM(o2, i2, K, dist, r2, t2);
      const Vec3 rv2(r2.at<double>(0), r2.at<double>(1), r2.at<double>(2));
      const Vec3 tv2(t2.at<double>(0), t2.at<double>(1), t2.at<double>(2));
      d.push_back(RotationVector(MaskRotation(m, PoseInC(aux, FromRvec(rv2), tv2)) * e.q_c_from_m.conjugate()));
    }
    Vec3 mean = Vec3::Zero();
    for (const auto& v : d) mean += v / nt;
    Mat3 jack = Mat3::Zero();
    for (const auto& v : d) jack += (v - mean) * (v - mean).transpose();
    jack *= (nt - 1.0) / nt;
    e.jackknife_cov_rad2 = jack;
    Vec3 scale;
    for (int k = 0; k < 3; ++k)
      scale(k) = std::sqrt(std::max(1.0, jack(k, k) / std::max(1e-30, e.q_c_from_m_cov_rad2(k, k))));
    e.q_c_from_m_cov_rad2 = scale.asDiagonal() * e.q_c_from_m_cov_rad2 * scale.asDiagonal();
  }
  return e;
}

}  // namespace ssiu
