#include "groundtest/reference.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "core/attitude.h"
#include "core/csv.h"
#include "core/error.h"
#include "core/image.h"
#include "groundtest/apriltag_family.h"
#include "groundtest/tag_edges.h"

namespace ssiu {

void FiducialOptions::Check() const {
  if (!(quad_decimate >= 1 && quad_decimate <= 4))
    throw InputError("fiducial options", "quad_decimate must be in [1, 4]");
  if (min_tags < 1) throw InputError("fiducial options", "min_tags must be >= 1");
  if (!(pixel_noise_dn >= 0)) throw InputError("fiducial options", "pixel_noise_dn must be >= 0");
}

PlatePoseEstimate EstimatePlatePoseFromFile(const Mask& m, const AuxCamera& aux, const std::string& photo,
                                            const FiducialOptions& o) {
  const Frame f = ReadFrame(photo);
  std::vector<uint8_t> px(f.image.pixels.size());
  const double scale = f.bit_depth == 8 ? 1.0 : 255.0 / std::max(1.0, f.saturation_adu);
  for (size_t i = 0; i < px.size(); ++i)
    px[i] = static_cast<uint8_t>(std::clamp(std::round(f.image.pixels[i] * scale), 0.0, 255.0));
  return EstimatePlatePose(m, aux, px.data(), f.image.width, f.image.height, photo, o);
}

ReferenceSample ReferenceFromStand(const Mask& m, const Quat& q_c_from_m, const Mat3& cov_cm, double az_rad,
                                   double el_rad, double rot_rad, double encoder_sigma_rad, double t_s) {
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
  WriteCsv(path,
           {"t_s", "qw", "qx", "qy", "qz", "sigma_cross_arcsec", "sigma_roll_arcsec", "common_sigma_cross_arcsec",
            "common_sigma_roll_arcsec"},
           cols);
}

}  // namespace ssiu
