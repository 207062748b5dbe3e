#include "groundtest/reference.h"

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

namespace ssiu {

void FiducialOptions::Check() const {
  if (!(quad_decimate >= 1 && quad_decimate <= 4)) throw InputError("fiducial options", "quad_decimate must be in [1, 4]");
  if (min_tags < 1) throw InputError("fiducial options", "min_tags must be >= 1");
}

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
    throw InputError(photo, "size " + std::to_string(width) + "x" + std::to_string(height) + " differs from the aux camera's " +
                                std::to_string(aux.camera.width) + "x" + std::to_string(aux.camera.height));
  const std::vector<FiducialDetection> dets = DetectFiducials(pixels, width, height, m.tag_family, o);
  if (dets.empty()) {
    for (const auto& other : groundtest_internal::KnownFamilies()) {
      if (other == m.tag_family) continue;
      if (!DetectFiducials(pixels, width, height, other, o).empty())
        throw InputError(photo, "shows " + other + " fiducials, but the mask uses " + m.tag_family + " (wrong tag family)");
    }
    throw InputError(photo, "no " + m.tag_family + " fiducials visible");
  }
  std::map<int, const MaskTag*> by_id;
  for (const auto& t : m.tags) by_id[t.id] = &t;
  std::vector<cv::Point3d> obj;
  std::vector<cv::Point2d> img;
  PlatePoseEstimate e;
  std::string foreign;
  for (const auto& d : dets) {
    auto it = by_id.find(d.id);
    if (it == by_id.end()) {
      foreign += (foreign.empty() ? "" : ",") + std::to_string(d.id);
      continue;
    }
    const auto corners = it->second->Corners();
    for (int k = 0; k < 4; ++k) {
      obj.emplace_back(corners[k].x(), corners[k].y(), 0.0);
      img.emplace_back(d.corners_px[k].x(), d.corners_px[k].y());
    }
    e.tag_ids.push_back(d.id);
  }
  if (static_cast<int>(e.tag_ids.size()) < o.min_tags)
    throw InputError(photo, std::to_string(e.tag_ids.size()) + " of this mask's " + m.tag_family + " fiducials visible (need " +
                                std::to_string(o.min_tags) + ")" + (foreign.empty() ? "" : "; tags " + foreign + " belong to another mask"));
  const Camera& c = aux.camera;
  const cv::Matx33d K(c.focal_length_px, 0, c.cx_px, 0, c.focal_length_px, c.cy_px, 0, 0, 1);
  const std::vector<double> dist = {c.distortion.k1, c.distortion.k2, c.distortion.p1, c.distortion.p2, c.distortion.k3};
  // Planar target: IPPE for the start, then Levenberg-Marquardt on all corners.
  cv::Mat rvec, tvec;
  if (!cv::solvePnP(obj, img, K, dist, rvec, tvec, false, cv::SOLVEPNP_IPPE))
    throw InputError(photo, "PnP pose of the fiducials failed");
  cv::solvePnPRefineLM(obj, img, K, dist, rvec, tvec);
  std::vector<cv::Point2d> proj;
  cv::Mat jac;
  cv::projectPoints(obj, rvec, tvec, K, dist, proj, jac);
  double rss = 0;
  for (size_t i = 0; i < img.size(); ++i) rss += std::pow(proj[i].x - img[i].x, 2) + std::pow(proj[i].y - img[i].y, 2);
  const int n_obs = static_cast<int>(2 * img.size());
  e.rms_reprojection_px = std::sqrt(rss / (n_obs / 2.0));
  e.corner_sigma_px = std::sqrt(rss / std::max(1, n_obs - 6));
  Eigen::MatrixXd J(n_obs, 6);
  for (int r = 0; r < n_obs; ++r)
    for (int k = 0; k < 6; ++k) J(r, k) = jac.at<double>(r, k);
  e.covariance = e.corner_sigma_px * e.corner_sigma_px * (J.transpose() * J).inverse();
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
    if (k < 3) r2(k) += h; else t2(k - 3) += h;
    const Quat q2 = MaskRotation(m, PoseInC(aux, FromRvec(r2), t2));
    G.col(k) = RotationVector(q2 * e.q_c_from_m.conjugate()) / h;
  }
  e.q_c_from_m_cov_rad2 = G * e.covariance * G.transpose();
  // The formal covariance treats the corners as independent; a tag's four corners share its edge
  // fits, so their errors are correlated. A leave-one-tag-out jackknife (Efron & Stein 1981) sees
  // that; each axis takes the larger of the two variances, keeping the formal correlations.
  const int nt = static_cast<int>(e.tag_ids.size());
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

PlatePoseEstimate EstimatePlatePoseFromFile(const Mask& m, const AuxCamera& aux, const std::string& photo,
                                            const FiducialOptions& o) {
  const Frame f = ReadFrame(photo);
  std::vector<uint8_t> px(f.image.pixels.size());
  const double scale = f.bit_depth == 8 ? 1.0 : 255.0 / std::max(1.0, f.saturation_adu);
  for (size_t i = 0; i < px.size(); ++i) px[i] = static_cast<uint8_t>(std::clamp(std::round(f.image.pixels[i] * scale), 0.0, 255.0));
  return EstimatePlatePose(m, aux, px.data(), f.image.width, f.image.height, photo, o);
}

ReferenceSample ReferenceFromStand(const Mask& m, const Quat& q_c_from_m, const Mat3& cov_cm, double az_rad, double el_rad,
                                   double rot_rad, double encoder_sigma_rad, double t_s) {
  ReferenceSample r;
  r.t_s = t_s;
  const Quat stand = StandRotation(az_rad, el_rad, rot_rad);
  r.q_inertial_from_sensor = (m.q_design * q_c_from_m.conjugate() * stand).normalized();
  // An error d_C of q_C_from_M appears in the sensor frame as -R^T d_C (R = stand rotation).
  const Mat3 R = stand.toRotationMatrix();
  r.common_covariance_rad2 = R.transpose() * cov_cm * R;
  r.covariance_rad2 = encoder_sigma_rad * encoder_sigma_rad * Mat3::Identity();
  r.sigma_cross_rad = std::sqrt((r.covariance_rad2(0, 0) + r.covariance_rad2(1, 1)) / 2);
  r.sigma_roll_rad = std::sqrt(r.covariance_rad2(2, 2));
  r.common_sigma_cross_rad = std::sqrt((r.common_covariance_rad2(0, 0) + r.common_covariance_rad2(1, 1)) / 2);
  r.common_sigma_roll_rad = std::sqrt(r.common_covariance_rad2(2, 2));
  return r;
}

void WriteReferenceCsv(const std::string& path, const std::vector<ReferenceSample>& s) {
  std::vector<std::vector<double>> cols(9);
  for (const auto& r : s) {
    const auto q = ToWxyz(r.q_inertial_from_sensor);
    cols[0].push_back(r.t_s);
    for (int k = 0; k < 4; ++k) cols[1 + k].push_back(q[k]);
    cols[5].push_back(r.sigma_cross_rad * kRadToArcsec);
    cols[6].push_back(r.sigma_roll_rad * kRadToArcsec);
    cols[7].push_back(r.common_sigma_cross_rad * kRadToArcsec);
    cols[8].push_back(r.common_sigma_roll_rad * kRadToArcsec);
  }
  WriteCsv(path, {"t_s", "qw", "qx", "qy", "qz", "sigma_cross_arcsec", "sigma_roll_arcsec", "common_sigma_cross_arcsec",
                  "common_sigma_roll_arcsec"},
           cols);
}

}  // namespace ssiu
