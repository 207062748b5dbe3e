// Reference quaternions for the pictures of a collimator ground test (`ssiu groundtest reference`).
//
//   PlatePoseEstimate p = EstimatePlatePose(mask, aux, photo, FiducialOptions{});  // AprilTag + PnP
//   ReferenceSample r = ReferenceFromStand(mask, p.q_c_from_m, p.q_c_from_m_cov_rad2, az, el, rot, sigma, t);
//
// q_ref = q_design * conj(q_C_from_M) * StandRotation(az, el, rot) (stand.h). The plate's pose in the
// collimator frame comes from the fiducials: libapriltag finds the tag36h11 corners, OpenCV's
// solvePnP gives the plate pose in the auxiliary camera, the camera's calibrated pose in C gives it
// in C. Its covariance is sigma^2 (J^T J)^-1 (J: reprojection Jacobian of the 6 pose parameters),
// with the corner noise sigma estimated from the PnP residuals (RSS / (2N - 6)), propagated to the
// mask rotation numerically; per axis it is raised to a leave-one-tag-out jackknife variance where
// that is larger (corners of one tag have correlated errors). Encoder noise adds sigma_enc^2 per axis (small-angle approximation).
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
  std::vector<int> tag_ids;                    // mask tags used
  PlatePose pose;                              // plate in C
  Mat3 r_aux_from_p = Mat3::Identity();        // PnP result
  Vec3 t_aux_mm = Vec3::Zero();
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();  // (rvec rad, t mm) in aux
  double corner_sigma_px = 0;                  // from the residuals
  double rms_reprojection_px = 0;
  Quat q_c_from_m = Quat::Identity();
  Mat3 q_c_from_m_cov_rad2 = Mat3::Zero();     // of its rotation vector, C frame (formal, or larger jackknife)
  Mat3 jackknife_cov_rad2 = Mat3::Zero();      // leave-one-tag-out estimate (3 or more tags)
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
  Mat3 covariance_rad2 = Mat3::Zero();         // per-picture part, sensor frame
  Mat3 common_covariance_rad2 = Mat3::Zero();  // plate-pose part, sensor frame
  double sigma_cross_rad = 0, sigma_roll_rad = 0;                // per picture (RMS of x and y; z)
  double common_sigma_cross_rad = 0, common_sigma_roll_rad = 0;  // common
};

ReferenceSample ReferenceFromStand(const Mask& m, const Quat& q_c_from_m, const Mat3& q_c_from_m_cov_rad2, double az_rad,
                                   double el_rad, double rot_rad, double encoder_sigma_rad, double t_s);

// t_s,qw,qx,qy,qz,sigma_cross_arcsec,sigma_roll_arcsec,common_sigma_cross_arcsec,common_sigma_roll_arcsec
void WriteReferenceCsv(const std::string& path, const std::vector<ReferenceSample>& samples);

}  // namespace ssiu
