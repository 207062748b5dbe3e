// Simulator of a redundant FOG unit on a moving body, with truth and a star-tracker log
// (`ssiu simulate gyro`). Every error term of GyroErrorModel is applied per gyro (docs/inertial.md).
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "core/json.h"
#include "core/types.h"
#include "inertial/gyro_unit.h"

namespace ssiu {

constexpr double kEarthRateRadS = 7.2921150e-5;  // IERS Conventions (2010), sidereal rate

// Piecewise-linear temperature: start_c, then segments of (duration_s, rate_c_per_min); constant after.
struct TemperatureProgramme {
  double start_c = 20.0;
  std::vector<std::array<double, 2>> segments;
  double TempC(double t_s) const;
  double RateCPerMin(double t_s) const;
};

// A fault injected on one gyro over [t_s, end_s): its output gains step_dph + ramp_dph_per_h *
// (t - t_s) / 3600 and white noise of noise_dph (1 sigma per sample: a noise burst), or, when stuck,
// holds the last output before t_s. Several faults (on one gyro or several) add up, in sequence or
// together; a stuck gyro ignores the others while stuck.
struct GyroFault {
  int gyro = 1;  // 1-based
  double t_s = 0;
  double step_dph = 0;
  double ramp_dph_per_h = 0;
  double noise_dph = 0;
  bool stuck = false;
  double end_s = std::numeric_limits<double>::infinity();  // the fault is gone from end_s on

  bool ActiveAt(double t) const { return t > t_s && t <= end_s; }  // sample interval ending at t
  Json ToJson() const;
};

// One step of a unit bench campaign: the unit mounted on a single-axis table (table axis up) with
// body vector `up_body` pointing up, the table at angle table_deg (right-handed about up, 0 = body
// frame's projection as mounted, turned to north) at the start and turning at rate_dps. rate_dps 0
// is a static position of a multi-position test (the gyros see the Earth rate only).
struct BenchSegment {
  double duration_s = 60.0;
  Vec3 up_body = Vec3::UnitZ();
  double table_deg = 0.0;
  double rate_dps = 0.0;
};

struct MotionProfile {
  // "static" (bench at rest on the Earth: the gyros see Earth rate), "slew" (constant body rate),
  // "sine" (rate amplitude_dps * sin(2 pi t / period_s) per body axis), "temperature" (static with
  // a temperature programme; a default programme when none is given), "bench" (a unit bench
  // campaign: the `bench` segments in sequence at latitude_deg, the last one held; the unit is
  // remounted between segments, so truth.csv is the integral of the rates, not a real attitude).
  std::string type = "slew";
  Quat q0 = Quat::Identity();      // body -> inertial at t = 0 (static: from latitude and azimuth)
  double latitude_deg = 45.0;      // static
  double azimuth_deg = 0.0;        // static: azimuth of body x from north towards east; body z up
  Vec3 axis_body = Vec3::UnitZ();  // slew
  double rate_dps = 0.1;           // slew
  double slew_start_s = 0.0;       // slew: at rest before, and from slew_end_s on
  double slew_end_s = std::numeric_limits<double>::infinity();
  std::vector<BenchSegment> bench;           // bench
  Vec3 amplitude_dps = Vec3(1.0, 0.5, 0.3);  // sine
  double period_s = 60.0;                    // sine
  Vec3 periods_s = Vec3::Zero();             // sine: per body axis (0: period_s), for turns about changing axes
  TemperatureProgramme temperature;
  Vec3 magnetic_field_body_ut = Vec3::Zero();
  // Star tracker: samples at multiples of 1/st_rate_hz, noise about body x, y (cross) and z (roll).
  double st_rate_hz = 1.0;
  double st_sigma_cross_arcsec = 5.0;
  double st_sigma_roll_arcsec = 30.0;
  std::vector<std::array<double, 2>> st_outages_s;  // [t0, t1): no star samples
  std::vector<GyroFault> faults;

  Vec3 RateBodyRadS(double t_s) const;  // true body rate relative to inertial space
  bool InStarOutage(double t_s) const;  // inside one of st_outages_s: the star tracker gives nothing
  void Check(const std::string& file, int n_gyros) const;
};

MotionProfile MotionProfileFromJson(const Json& j, const std::string& file);
// The default unit bench campaign (`ssiu simulate gyro --profile bench`, docs/fog-calibration.md):
// six mountings (body +-x, +-y, +-z up), each with two static positions 180 deg apart on the table
// (120 s each) and table rates of +-2, +-10, +-30 deg/s (60 s each): 3600 s in all, at 45 deg
// latitude, with a slow laboratory temperature drift of about 1 C.
MotionProfile BenchCampaignProfile();
double BenchDurationS(const MotionProfile& p);  // sum of the bench segments
GyroFault GyroFaultFromJson(const Json& j, const std::string& file);
MotionProfile LoadMotionProfile(const std::string& path);

struct GyroSimOptions {
  double duration_s = 3600.0;
  uint64_t seed = 1;
  void Check() const;
};

struct GyroSimulation {
  // Gyro samples k = 1..K at t = k / rate_hz, each the mean output over ((k-1)/rate, k/rate].
  std::vector<double> t_s;
  std::vector<GyroVec> gyro_dph;
  std::vector<double> temp_c;
  // Truth at the same times.
  std::vector<Quat> q_true;
  std::vector<Vec3> w_true_dph;     // instantaneous body rate
  std::vector<Vec3> w_mean_dph;     // mean body rate over each sample's interval (a bench's reference)
  bool bench_reference = false;     // a bench profile: gyro.csv carries ref_x_dph,ref_y_dph,ref_z_dph
  std::vector<Vec3> body_bias_dph;  // least-squares body-axis image of the gyros' slow errors (bias,
                                    // flicker, rate random walk, thermal, magnetic, faults): what a
                                    // filter's bias estimate should track
  Quat q0 = Quat::Identity();
  // Star tracker.
  std::vector<double> st_t_s;
  std::vector<Quat> st_q;
  double st_sigma_cross_arcsec = 0, st_sigma_roll_arcsec = 0;
};

GyroSimulation SimulateGyro(const GyroUnit& unit, const MotionProfile& profile, const GyroSimOptions& options);

// Writes DIR/gyro.csv (t_s,g1_dph..gN_dph,temp_c, and for a bench profile ref_x_dph,ref_y_dph,
// ref_z_dph = w_mean_dph: the unit bench log of conventions.md), DIR/truth.csv (t_s,qw,qx,qy,qz),
// DIR/rates.csv (t_s,wx_dph,wy_dph,wz_dph,bx_dph,by_dph,bz_dph), DIR/st.csv
// (t_s,qw,qx,qy,qz,sigma_cross_arcsec,sigma_roll_arcsec) and DIR/unit.json.
void WriteGyroSimulation(const std::string& dir, const GyroSimulation& sim, const GyroUnit& unit);

}  // namespace ssiu
