#include "inertial/fuse_adm.h"

#include <algorithm>

namespace ssiu {

double SigmaVRadS05(double arw_deg_per_sqrt_h) { return arw_deg_per_sqrt_h / 60.0 * kDegToRad; }
double SigmaURadS15(double bias_walk_dph_per_sqrt_h) { return bias_walk_dph_per_sqrt_h / 3600.0 / 60.0 * kDegToRad; }

AdmSensor StarTrackerSensor(int number, int head, double sigma_cross_arcsec, double sigma_roll_arcsec, double rate_hz) {
  const double c = sigma_cross_arcsec * kArcsecToRad, r = sigma_roll_arcsec * kArcsecToRad;
  return {number, "AST_" + std::to_string(head), {c, c, r}, rate_hz};
}

AdmSensor GyroSensor(int number, double arw_deg_per_sqrt_h, double rate_hz) {
  AdmSensor s{number, "GYRO", {}, rate_hz};
  if (rate_hz > 0) s.noise_sigma_rad.assign(3, SigmaVRadS05(arw_deg_per_sqrt_h) / std::sqrt(rate_hz));
  return s;
}

double MedianRateHz(const std::vector<double>& t_s) {
  if (t_s.size() < 2) return 0.0;
  std::vector<double> dt(t_s.size() - 1);
  for (size_t k = 1; k < t_s.size(); ++k) dt[k - 1] = t_s[k] - t_s[k - 1];
  std::nth_element(dt.begin(), dt.begin() + dt.size() / 2, dt.end());
  const double m = dt[dt.size() / 2];
  return m > 0 ? 1.0 / m : 0.0;
}

AttitudeHistory FusedAttitudeHistory(const std::vector<FusedSample>& samples, const std::string& epoch_utc,
                                     const Json& noise, const std::vector<AdmSensor>& sensors) {
  AttitudeHistory h;
  h.epoch_utc = epoch_utc;
  h.basis = "DETERMINED_GND";
  h.cov_type = "ANGLE_GYROBIAS";
  for (const FusedSample& s : samples) {
    if (!h.states.empty() && !(s.t_s > h.states.back().t_s)) continue;  // one attitude per epoch
    AdmState a;
    a.t_s = s.t_s;
    a.q_inertial_from_body = s.q_inertial_from_body;
    a.gyro_bias_rad_s = s.bias_dph * kDphToRadS;
    a.w_body_rad_s = s.w_body_rad_s;
    h.states.push_back(a);
    AdmCovariance c;
    c.t_s = s.t_s;
    for (int i = 0; i < 3; ++i) c.diagonal.push_back(s.sigma_rad[i] * s.sigma_rad[i]);
    for (int i = 0; i < 3; ++i) c.diagonal.push_back(std::pow(s.bias_sigma_dph[i] * kDphToRadS, 2));
    h.covariances.push_back(c);
  }
  AdmDetermination d;
  d.method = "EKF";
  d.sigma_v_rad_s05 = SigmaVRadS05(noise.value("arw_deg_per_sqrt_h", 0.0));
  d.sigma_u_rad_s15 = SigmaURadS15(noise.value("bias_walk_dph_per_sqrt_h", 0.0));
  d.sensors = sensors;
  h.determination = d;
  return h;
}

}  // namespace ssiu
