// Reference vs computed attitudes of a ground test (`ssiu groundtest compare`).
//
//   CompareResult r = CompareAttitudes(ReadAttitudeSeries(ref_csv), ReadAttitudeSeries(st_csv), CompareOptions{});
//
// Per picture the error e = RotationVector(conj(q_ref) * q_est) in the tracker's sensor frame
// (cross-boresight |e_xy| and roll e_z). A fixed stand-to-tracker misalignment is a constant e; it is
// estimated as the weighted mean of e (weights 1/(sigma_ref^2 + sigma_est^2) per axis when both files
// carry sigmas, else equal), with its standard error scaled by the Birge ratio sqrt(chi2/dof) when the
// scatter exceeds the stated sigmas, plus (in quadrature) the mean common-mode sigma, which no
// number of pictures averages down. It is removed, and the residuals give RMS, maximum, linear drift
// (arcsec per hour, least squares) and chi2/dof against the stated sigmas. Pass: residual RMS
// cross-boresight <= requirement and roll <= the roll requirement.
#pragma once

#include <string>
#include <vector>

#include "core/json.h"
#include "core/types.h"

namespace ssiu {

struct AttitudeSample {
  double t_s = 0;
  Quat q = Quat::Identity();
  double sigma_cross_rad = 0, sigma_roll_rad = 0;                // 0 = not given
  double common_sigma_cross_rad = 0, common_sigma_roll_rad = 0;  // error shared by all pictures (reference.h)
};
// t_s,qw,qx,qy,qz[,sigma_cross_arcsec,sigma_roll_arcsec][,common_sigma_cross_arcsec,common_sigma_roll_arcsec];
// InputError naming file/column/row, for
// unsorted times, for fewer than one row.
// Or a CCSDS AEM/ACM (ccsds/adm.h), sigmas from an ACM's ANGLE covariance (cross: RMS of x and y), t_s
// after *epoch_utc when given and not empty, else after the message's epoch (the ACM's EPOCH_TZERO, the
// AEM's first epoch), which is then stored in *epoch_utc: reading the reference, then the computed
// series with the same string puts both on one time axis.
std::vector<AttitudeSample> ReadAttitudeSeries(const std::string& path, std::string* epoch_utc = nullptr);

struct CompareOptions {
  double requirement_arcsec = 10.0;      // cross-boresight 1-sigma (RMS) requirement
  double roll_requirement_arcsec = 0.0;  // 0 = 8 x requirement_arcsec (a typical tracker's roll/cross ratio)
  double time_tolerance_s = 0.5;         // a computed attitude belongs to the reference within this time
  bool remove_misalignment = true;
  void Check() const;
};

struct AxisStats {
  double mean = 0, rms = 0, max_abs = 0;
  double drift_per_h = 0, drift_sigma_per_h = 0;  // linear trend of the residual
};

struct CompareResult {
  int pictures = 0, unmatched = 0;
  std::vector<double> t_s;
  std::vector<Vec3> error_rad;     // per picture, sensor frame, before removal
  std::vector<Vec3> residual_rad;  // after the misalignment is removed
  Vec3 misalignment_rad = Vec3::Zero();
  Vec3 misalignment_sigma_rad = Vec3::Zero();
  double birge_ratio = 1;   // sqrt(chi2/dof) of the residuals against the stated sigmas
  double chi2_per_dof = 0;  // 0 when no sigmas were given
  AxisStats x, y, roll;     // residuals (rad)
  double rms_cross_rad = 0, max_cross_rad = 0, rms_total_rad = 0, max_total_rad = 0;
  double raw_rms_cross_rad = 0, raw_rms_roll_rad = 0;        // before removal
  double mean_sigma_cross_rad = 0, mean_sigma_roll_rad = 0;  // stated (tracker+reference) 1-sigma, RMS
  double requirement_cross_rad = 0, requirement_roll_rad = 0;
  bool pass = false;
  std::string verdict;
};

CompareResult CompareAttitudes(const std::vector<AttitudeSample>& reference,
                               const std::vector<AttitudeSample>& computed, const CompareOptions& o,
                               const std::string& computed_name = "computed");
Json CompareResultToJson(const CompareResult& r);
// DIR/errors.png (cross-boresight and roll per picture, misalignment lines) and DIR/residuals.png.
void WriteComparePlots(const CompareResult& r, const std::string& dir);

}  // namespace ssiu
