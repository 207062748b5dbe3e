// Reference quaternions for the pictures of a collimator ground test (`ssiu groundtest reference`).
//
//   PlatePoseEstimate p = EstimatePlatePose(mask, aux, photo, FiducialOptions{});  // AprilTag + PnP
//   ReferenceSample r = ReferenceFromStand(mask, p.q_c_from_m, p.q_c_from_m_cov_rad2, az, el, rot, sigma, t);
//
// q_ref = q_design * conj(q_C_from_M) * StandRotation(az, el, rot) (stand.h). The plate's pose in the
// collimator frame comes from the fiducials: libapriltag finds the tag36h11 tags, a blurred-step
// model fit of each tag's four sides gives its corners and their covariance from the photo's pixel
// noise (tag_edges.h), OpenCV's solvePnP gives the plate pose in the auxiliary camera, the camera's
// calibrated pose in C gives it in C. Its covariance is the least-squares sandwich
// (J^T J)^-1 J^T Sigma J (J^T J)^-1 (J: reprojection Jacobian of the 6 pose parameters, Sigma: the
// corners' covariance), propagated to the mask rotation numerically: the accuracy the pixel noise
// allows. It is scaled by the PnP residuals' chi2/dof when they scatter more, and per axis raised to a
// leave-one-tag-out jackknife variance where that is larger. Encoder noise adds sigma_enc^2 per axis
// (small-angle approximation).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/types.h"
#include "groundtest/mask.h"
#include "groundtest/stand.h"
#include "groundtest/virtual_stand.h"

namespace ssiu {

struct FiducialOptions {
  double quad_decimate = 1.0;  // libapriltag: 1 = full resolution (best corners)
  int min_tags = 2;            // fewer mask tags found -> bad input
  bool refine_corners = true;  // edge-model fit of each tag's sides (tag_edges.h) instead of libapriltag's corners
  double pixel_noise_dn = 0;   // the photo's pixel noise (8-bit counts); 0 = measured from the edge fits
  void Check() const;
};

struct FiducialDetection {
  int id = -1;
  std::array<Vec2, 4> corners_px;  // ssiu pixel convention (pixel (0,0) = centre of the top-left pixel)
  double decision_margin = 0;
  int hamming = 0;
};

// All tags of `family` in an 8-bit grey image.
std::vector<FiducialDetection> DetectFiducials(const uint8_t* pixels, int width, int height, const std::string& family,
                                               const FiducialOptions& o);

struct PlatePoseEstimate {
  std::vector<int> tag_ids;              // mask tags used
  PlatePose pose;                        // plate in C
  Mat3 r_aux_from_p = Mat3::Identity();  // PnP result
  Vec3 t_aux_mm = Vec3::Zero();
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();  // (rvec rad, t mm) in aux
  int refined_tags = 0;                  // tags whose corners come from the edge-model fit
  double pixel_noise_dn = 0;             // used for the prediction (given, or measured)
  double measured_pixel_noise_dn = 0;    // RMS residual of the edge fits
  double predicted_corner_sigma_px = 0;  // RMS corner sigma from the pixel noise (per coordinate)
  double corner_sigma_px = 0;            // from the PnP residuals
  double corner_chi2_per_dof = 0;        // PnP residuals against the predicted corner covariance
  double rms_reprojection_px = 0;
  Quat q_c_from_m = Quat::Identity();
  Mat3 q_c_from_m_noise_cov_rad2 = Mat3::Zero();  // what the pixel noise alone allows (prediction)
  Mat3 q_c_from_m_cov_rad2 = Mat3::Zero();        // stated: the prediction x max(1, chi2/dof), or the larger jackknife
  Mat3 jackknife_cov_rad2 = Mat3::Zero();         // leave-one-tag-out estimate (3 or more tags)
};

// Throws InputError naming `photo_name` when no tag of the mask's family is visible (naming another
// family when that is what the photo shows), when the tags are not this mask's, or too few are seen.
PlatePoseEstimate EstimatePlatePose(const Mask& m, const AuxCamera& aux, const uint8_t* pixels, int width, int height,
                                    const std::string& photo_name, const FiducialOptions& o = {});
// Reads an 8-bit (or 16-bit, scaled) grey photo and estimates the pose.
PlatePoseEstimate EstimatePlatePoseFromFile(const Mask& m, const AuxCamera& aux, const std::string& photo,
                                            const FiducialOptions& o = {});

// The reference error has two parts: the encoders' noise, independent from picture to picture, and
// the plate pose, common to all pictures of one plate set-up (the fiducial corners' errors are
// mostly fixed by the geometry, so more photos do not average them down). `compare` averages the
// first and not the second.
struct ReferenceSample {
  double t_s = 0;
  Quat q_inertial_from_sensor = Quat::Identity();
  Mat3 covariance_rad2 = Mat3::Zero();                           // per-picture part, sensor frame
  Mat3 common_covariance_rad2 = Mat3::Zero();                    // plate-pose part, sensor frame
  double sigma_cross_rad = 0, sigma_roll_rad = 0;                // per picture (RMS of x and y; z)
  double common_sigma_cross_rad = 0, common_sigma_roll_rad = 0;  // common
};

ReferenceSample ReferenceFromStand(const Mask& m, const Quat& q_c_from_m, const Mat3& q_c_from_m_cov_rad2,
                                   double az_rad, double el_rad, double rot_rad, double encoder_sigma_rad, double t_s);

// t_s,qw,qx,qy,qz,sigma_cross_arcsec,sigma_roll_arcsec,common_sigma_cross_arcsec,common_sigma_roll_arcsec
void WriteReferenceCsv(const std::string& path, const std::vector<ReferenceSample>& samples);

}  // namespace ssiu
