// The edges of the Allan analysis: reading a gyro rate log or an already computed Allan curve (with
// its rate unit), and writing the report (JSON in conventional gyro units) and the plot.
// Everything read is converted to rad/s; every error on input is an InputError naming file and field.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "calibration/allan.h"
#include "core/json.h"

namespace ssiu {

enum class RateUnit { kRadPerS, kDegPerS, kDegPerH };
const char* RateUnitName(RateUnit unit);  // "rad/s", "deg/s", "deg/h"
inline std::ostream& operator<<(std::ostream& os, RateUnit v) { return os << RateUnitName(v); }
double RateUnitToRadPerS(RateUnit unit);  // a value in `unit` times this is in rad/s
// Unit from a column name's suffix (_dph, _dps, _rps, _rad_s, _deg_s, _deg_h); false if none.
bool RateUnitFromName(const std::string& column, RateUnit* unit);
// "rad/s", "deg/s", "deg/h" (also "rps", "dps", "dph"); InputError naming `file` otherwise.
RateUnit ParseRateUnit(const std::string& text, const std::string& file);

struct RateLog {
  std::string file, column;
  RateUnit unit = RateUnit::kRadPerS;
  double sample_rate_hz = 0;
  std::vector<double> rate_rad_s;
};

// One rate column of a CSV log. The sample rate comes from `t_s` (which must increase with no gaps:
// every step within 50% of the median step) unless `sample_rate_hz` > 0 is given; the unit from the
// column name unless `unit` is given (else an InputError asks for --unit).
RateLog ReadRateLog(const std::string& path, const std::string& column, const std::string& unit = "",
                    double sample_rate_hz = 0);

struct CurveFileOptions {
  std::string tau_column;     // "" = autodetect (tau_s, tau, ...)
  std::string adev_column;    // "" = autodetect (adev*, else avar*)
  std::string channel;        // rows of this channel (needed when the file holds several)
  std::string tau_file;       // taus in a separate one-column file (imu_utils layout)
  std::string unit;           // "" = from the ADEV column name
  double sample_rate_hz = 0;  // with n or duration_s: edf from the formulas (else from the file)
  double n = 0;               // rate samples behind the curve
  double duration_s = 0;      // log length behind the curve (n = duration * rate)
  double confidence = 0.683;
};

struct CurveFile {
  AllanCurve curve;  // adev (and its interval) in rad/s
  std::string file, channel, tau_column, adev_column;
  RateUnit unit = RateUnit::kRadPerS;
  std::vector<std::string> channels;  // all channels in the file
};

// Reads an Allan curve: CSV with a header (e.g. SMAC-Group avar exports: channel,tau_s,avar,adev,
// adev_lci,adev_uci,rel_error, with '#' comment lines whose "freq_hz=" and "n=" are used), or a
// header-less one-column ADEV file with `tau_file` (imu_utils). edf from an `edf` column, else
// 1/(2 rel_error^2), else the formulas when n is known, else assumed equal (uncertainties then come
// from the fit's scatter alone).
CurveFile ReadAllanCurveFile(const std::string& path, const CurveFileOptions& options);

// Noise terms in conventional gyro units from a fit to a curve in rad/s.
struct GyroNoiseTerms {
  NoiseTerm quantization_arcsec, arw_deg_per_sqrt_h, bias_instability_dph, rrw_deg_per_h_per_sqrt_h,
      rate_ramp_deg_per_h2;
  NoiseTerm bias_instability_floor_dph;  // the curve's minimum / 0.664 (IEEE 952 Annex C), at its tau
};
GyroNoiseTerms ToGyroUnits(const NoiseFit& fit_rad_s);

// The report: curve (ADEV in deg/h), the fitted terms in conventional units, and provenance.
Json AllanReportJson(const AllanCurve& curve_rad_s, const NoiseFit& fit, const Json& provenance, double confidence);

// Log-log plot of ADEV in deg/h with error bars, the fitted model and its dominant terms.
void WriteAllanPlot(const std::string& path, const AllanCurve& curve_rad_s, const NoiseFit& fit,
                    const std::string& title);

}  // namespace ssiu
