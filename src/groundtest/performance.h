// The ECSS-E-ST-60-20C split of one optical head's attitude error (`ssiu performance`).
//
//   PerformanceReport r = AnalysePerformance(measured, reference, camera, temperature, PerformanceOptions{});
//
// The error e(t) = RotationVector(conj(q_ref) q_meas) in the sensor frame, [x, y, roll], is split into
// the contributions ECSS-E-ST-60-20C names (Rev.1 clause 3.2.8: 3.2.8.2 bias, 3.2.8.3 FOV spatial error,
// 3.2.8.4 pixel spatial error, with the temporal noise and thermo-elastic error beside them; its notes
// convert the spatial errors to the time domain through the sensor's rate, as done here), each told
// apart by what distinguishes it:
// - bias: the mean of e (the standard's bias, whose metric is the mean error, Annex B.5.7);
// - thermo-elastic: the part that follows the temperature, a least-squares line of e on temp_c (interpolated
//   at each sample), reported as |slope| x std(temp_c), the 1-sigma it contributes over the test;
// - FOV spatial: the residual's power at low frequencies, up to `fov_band_crossings` x the field-crossing
//   frequency v / L (stars cross the field of length L at v px/s: an error that is a function of where
//   the stars are varies on that time scale);
// - pixel spatial: the power around the pixel-crossing frequencies v_x and v_y (px/s: a pattern that
//   repeats every pixel) and their harmonics, aliased to the sample rate, in bands as wide as the FOV band;
// - temporal noise: white, its level per frequency bin the median over the bins outside those bands
//   and above half the Nyquist frequency (over ln 2: the median of an exponential distribution); that floor is also
//   removed from the FOV and pixel bands, and a band's excess counts only above 3 sigma of the noise power in it. The
//   bands are wide (40 field crossings by default) because stars entering and leaving the field turn the spatial errors
//   into steps, whose spectrum falls only as 1/f^2.
// Powers come from the periodogram of each axis (no taper: see the .cc), normalised so that the bins sum to the
// variance (Parseval); each contribution is the square root of its band's power above the noise floor.
// The star image velocity is the reference's mean rate seen near the boresight: v = (-w_y fx, w_x fy).
#pragma once

#include <string>
#include <vector>

#include "core/camera.h"
#include "core/json.h"
#include "groundtest/compare.h"

namespace ssiu {

struct PerformanceOptions {
  double fov_band_crossings = 40.0;  // FOV band: f <= this x field-crossing frequency
  int pixel_harmonics = 2;           // pixel bands around m x pixel-crossing frequency, m = 1..this
  double time_tolerance_s = 1e-3;    // a measured attitude pairs with the reference within this time
  void Check() const;                // InputError naming the field
};

struct TemperatureLog {
  std::string file;
  std::vector<double> t_s, temp_c;
};
// CSV t_s,temp_c (conventions.md); InputError naming file/column/row.
TemperatureLog ReadTemperatureLog(const std::string& path);

struct PerformanceReport {
  int samples = 0;
  double sample_rate_hz = 0, span_s = 0;
  Vec3 rate_rad_s = Vec3::Zero();  // reference's mean rate, sensor axes
  Vec2 star_velocity_px_s = Vec2::Zero();
  double field_crossing_hz = 0;               // v / L
  Vec2 pixel_crossing_hz = Vec2::Zero();      // |v_x|, |v_y| (before aliasing)
  double fov_band_hz = 0;                     // FOV band upper edge; pixel bands are +- this around their centres
  std::vector<double> pixel_band_centres_hz;  // aliased to [0, sample_rate / 2]
  // The contributions, [x, y, roll] (rad): bias the mean, the others 1-sigma.
  Vec3 bias_rad = Vec3::Zero(), temporal_noise_rad = Vec3::Zero(), fov_spatial_rad = Vec3::Zero(),
       pixel_spatial_rad = Vec3::Zero(), thermoelastic_rad = Vec3::Zero();
  // The smallest FOV / pixel spatial error the test can tell from its noise (3 sigma of the noise
  // power in the band); a contribution below it is reported as 0.
  Vec3 fov_limit_rad = Vec3::Zero(), pixel_limit_rad = Vec3::Zero();
  Vec3 thermoelastic_rad_per_c = Vec3::Zero();  // slope of e on temperature
  double temperature_sigma_c = 0;               // 1-sigma of temp_c over the test (0 without a log)
  Vec3 total_rad = Vec3::Zero();                // 1-sigma of e about its mean
  std::vector<std::string> warnings;
  // For the plots: per sample time, error, temperature and the parts (band-passed residual).
  std::vector<double> t_s, temp_c;
  std::vector<Vec3> error_rad, thermal_rad, fov_rad, pixel_rad, noise_rad;
  std::vector<double> freq_hz;  // periodogram bins (one-sided) and their power, rad^2 per bin
  std::vector<Vec3> power_rad2;
};

// `measured` and `reference` pair by time (within options.time_tolerance_s); the paired samples must
// be (nearly) evenly spaced. `temperature` may be empty. InputError for fewer than 64 pairs, a gap,
// a reference that does not move (no crossing frequencies), a temperature log that does not cover the test.
PerformanceReport AnalysePerformance(const std::vector<AttitudeSample>& measured,
                                     const std::vector<AttitudeSample>& reference, const Camera& camera,
                                     const TemperatureLog& temperature, const PerformanceOptions& options);

// The JSON contract: bias_arcsec, temporal_noise_arcsec, fov_spatial_arcsec, pixel_spatial_arcsec,
// thermoelastic_arcsec as [x, y, roll], plus the frequencies and bands used.
Json PerformanceReportToJson(const PerformanceReport& r);

// DIR/error_parts.png (the error and its parts over time), DIR/spectrum.png (periodogram with the
// bands), DIR/error_vs_temperature.png (when a temperature log was given).
void WritePerformancePlots(const PerformanceReport& r, const std::string& dir);

// A simulated slow slew for tests and examples: random stars (density per square degree) seen by
// `camera` while the sensor turns at rate_rad_s (sensor axes) for duration_s at rate_hz; per sample
// QUEST on the stars' perturbed centroids. Injected, each alone and all together: bias (a fixed
// rotation), distortion (Brown k1 the solver does not know), an intra-pixel pattern (amplitude_px
// sin(2 pi x), sin(2 pi y)), white centroid noise, and a mount drift of drift_rad_per_c x temperature.
struct PerformanceSimulation {
  Camera camera;
  Vec3 rate_rad_s = Vec3::Zero();
  double rate_hz = 10, duration_s = 600, stars_per_deg2 = 0.5;
  unsigned seed = 1;
  Vec3 bias_rad = Vec3::Zero();
  double distortion_k1 = 0, intra_pixel_px = 0, noise_px = 0;  // k1 of the normalised radius (Brown)
  Vec3 drift_rad_per_c = Vec3::Zero();
  double temp_amplitude_c = 0, temp_period_s = 0;  // temp_c = 20 + amplitude sin(2 pi t / period)
};
struct SimulatedPerformance {
  std::vector<AttitudeSample> measured, reference;
  TemperatureLog temperature;
  // The truth of each contribution alone, [x, y, roll] (rad): 1-sigma about its mean; the bias is the
  // mean of the whole error (the fixed bias plus the means the other contributions happen to have).
  Vec3 bias_rad, fov_rad, pixel_rad, noise_rad, thermal_rad;
};
SimulatedPerformance SimulatePerformance(const PerformanceSimulation& s);

}  // namespace ssiu
