// A fused attitude history as a CCSDS attitude message (ccsds/adm.h): `ssiu fuse --aem/--acm` and
// `ssiu run --aem/--acm`. The AEM and ACM carry the angular velocity (the gyro rate, bias removed), the ACM
// also the gyro bias (a second ATT block, RATE_TYPE GYRO_BIAS), the filter's covariance
// per epoch (COV_TYPE ANGLE_GYROBIAS: attitude error and bias, body axes) and the determination (AD:
// EKF, the gyro noise as SIGMA_U / SIGMA_V, the sensors with their noise and rate).
#pragma once

#include <string>
#include <vector>

#include "ccsds/adm.h"
#include "inertial/fuse.h"

namespace ssiu {

// The gyro noise of the filter in ADM 2.0's terms (Farrenkopf's model, 504.0-B-2 ACM AD section):
// SIGMA_V, angle random walk, deg/sqrt(h) -> rad/s^0.5 (/ 60); SIGMA_U, rate random walk (the bias
// walk), deg/h/sqrt(h) -> rad/s^1.5 (/ 3600 / 60).
double SigmaVRadS05(double arw_deg_per_sqrt_h);
double SigmaURadS15(double bias_walk_dph_per_sqrt_h);

// The samples as a history in the body frame SC_BODY_1 relative to ICRF, t_s after epoch_utc.
// `noise` is FuseResult::noise (arw_deg_per_sqrt_h, bias_walk_dph_per_sqrt_h); `sensors` the AD's.
AttitudeHistory FusedAttitudeHistory(const std::vector<FusedSample>& samples, const std::string& epoch_utc,
                                     const Json& noise, const std::vector<AdmSensor>& sensors);

// The AD section's sensors: star-tracker head `head` (1-based, AST_<head>) with its 1-sigma noise
// about x, y (cross-boresight) and z (roll); the gyros with the angle noise of one sample,
// SIGMA_V sqrt(1 / rate). Rates in Hz (0 = not stated).
AdmSensor StarTrackerSensor(int number, int head, double sigma_cross_arcsec, double sigma_roll_arcsec, double rate_hz);
AdmSensor GyroSensor(int number, double arw_deg_per_sqrt_h, double rate_hz);

// Median sample rate (Hz) of a time column; 0 with fewer than two samples.
double MedianRateHz(const std::vector<double>& t_s);

}  // namespace ssiu
