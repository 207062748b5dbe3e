// Star-inertial fusion: gyro logs propagate the attitude, star-tracker quaternions correct it in a
// multiplicative EKF that also estimates the three gyro biases; a redundant unit is watched for a
// failing gyro (fdi.h). The library call behind `ssiu fuse`.
#pragma once

#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "core/json.h"
#include "core/types.h"
#include "inertial/fdi.h"
#include "inertial/gyro_unit.h"
#include "inertial/mekf.h"
#include "inertial/unit_calibrator.h"

namespace ssiu {

// A gyro log (conventions.md): t_s plus either body rates wx_dph,wy_dph,wz_dph or the raw outputs
// g1_dph..gN_dph of a unit. Row k holds the mean rate over (t_{k-1}, t_k], as an FOG outputs it.
struct GyroLog {
  std::string file;
  std::vector<double> t_s;
  std::vector<GyroVec> rates_dph;  // body rates (3) or gyro outputs (N)
  bool body_rates = false;
};

// A star-tracker log: t_s,qw,qx,qy,qz (body -> inertial), optional sigma_cross_arcsec,sigma_roll_arcsec.
struct StarTrackerLog {
  std::string file;
  std::string epoch_utc;  // UTC of t_s = 0 when read from a CCSDS message, else
  std::vector<double> t_s;
  std::vector<Quat> q_inertial_from_body;
  std::vector<double> sigma_cross_arcsec, sigma_roll_arcsec;  // empty when the columns are absent
};

// Reads a gyro log: body rates when wx_dph is present; otherwise g1_dph..gN_dph with N = `n_gyros`
// when > 0, else as many g*_dph columns as are found. InputError (file, column, row) for a missing column, a non-number
// or NaN, a time column that does not strictly increase, or fewer than 2 rows.
GyroLog ReadGyroLog(const std::string& path, int n_gyros = 0);
// The star-tracker log is that CSV or a CCSDS AEM/ACM (KVN or XML, ccsds/adm.h): its quaternions, and
// from an ACM's ANGLE covariance the sigmas (cross: RMS of x and y, roll: z). t_s counts from
// `epoch_utc`, "" = the ACM's EPOCH_TZERO or the AEM's first epoch (log.epoch_utc says which).
StarTrackerLog ReadStarTrackerLog(const std::string& path, const std::string& epoch_utc = "");

// The estimator's policies (OnlineFusion, the one MEKF + fault detection core behind both Fuse and
// the unit processor): the defaults are the values the filter was tuned and measured with
// (docs/inertial.md "The filter" and "Gyro faults").
struct FusionPolicy {
  // After this many consecutive NIS rejections the next star fix is taken ungated: a run of
  // rejections means the filter, not the star tracker, is wrong, and it must not lock itself out.
  int accept_after_rejections = 5;
  // A star gap longer than this breaks the star-rate isolator's chain of consecutive samples (a rate
  // across a long gap would mix the fault with the attitude drift).
  double isolation_chain_gap_s = 5.0;
  // Status "failed" when degraded and no star fix has been accepted for this long.
  double failed_after_s = 30.0;
  // Status "degraded" this long after an isolation (the bias re-converging on the remaining gyros).
  double settle_after_isolation_s = 10.0;
  // Status "degraded" once an isolation has left no spare gyro (three in use): without parity a new
  // fault is seen only by the star innovations, 8-20 s into a slow ramp, and the attitude is not
  // trustworthy to its sigma meanwhile (docs/inertial.md "Covariance and status"). The standard
  // meaning of degraded: the unit has lost its fault tolerance.
  bool degraded_without_spare = true;
  // The bias estimates at accepted fixes are kept this long: an isolation restores the bias from
  // before the fault's onset.
  double bias_history_s = 120.0;
  // Input checks (OnlineFusion::AddGyro's GyroSampleStatus). A gyro output beyond this magnitude
  // (deg/h) is unusable like a NaN: 3.6e6 deg/h = 1000 deg/s, beyond any FOG's range.
  double max_gyro_output_dph = 3.6e6;
  // A gyro sample more than this after the previous one is a time jump: taken only when the next
  // sample confirms it (one corrupt time tag must not lock out every later sample), and the attitude
  // is then taken afresh from the next star solution (the gyros did not cover the gap). The same for
  // a star solution this far beyond the filter's time (the gyros silent): the second one confirms.
  double max_gyro_gap_s = 10.0;
  // This many consecutive gyro samples before the last accepted one, in order among themselves: the
  // clock went back (or the last accepted time tag was corrupt). The stream's time is taken from the
  // last of them and the attitude restarts from the next star fix (whatever its time).
  int resync_after_samples = 100;
  // Fixed storage, reserved at construction so that the per-sample calls never allocate: fault
  // events kept (beyond it the oldest resolved event is dropped, counted by n_faults_dropped()), bias
  // estimates kept for bias_history_s (beyond it the oldest go first), star samples a fault's
  // isolator keeps (beyond it the oldest go first; at 10 Hz, 120 s need 1,200).
  int max_fault_events = 32;
  int bias_history_max = 4096;
  int max_star_samples_kept = 4096;

  void Check() const;  // InputError naming the field
};

struct FuseOptions {
  // Star-tracker noise when the log has no sigma columns (1 sigma; cross-boresight about body x, y,
  // roll about body z: the tracker's boresight is taken along body +Z).
  double st_sigma_cross_arcsec = 5.0;
  double st_sigma_roll_arcsec = 30.0;
  double init_bias_sigma_dph = 10.0;             // prior on each body-axis bias
  double bias_drift_floor_dph_per_sqrt_h = 0.0;  // added to the bias walk derived from the unit
  double nis_gate = 50.0;                        // reject star samples with NIS above this (chi^2, 3 dof)
  bool fdi = true;                               // fault detection/isolation (needs 4+ gyros)
  FdiOptions fdi_options;
  FusionPolicy policy;   // rejection, gap, status and history policies
  int output_every = 1;  // write every n-th gyro sample
  // OnlineFusion (the unit's processor): estimate the unit's scale factors and axis tilts from the
  // star attitudes as it goes (unit_calibrator.h, 4+ gyros) and correct the gyro outputs by them once
  // the windows determine every term (the estimate is the posterior mean under calibration's prior).
  // Off by default: the flight core's budget is set without it. The batch Fuse() leaves this to
  // CalibrateUnitInFlight (`ssiu fuse --calibrate-unit`).
  bool calibrate_unit = false;
  InflightCalOptions calibration = [] {
    InflightCalOptions c;
    c.prior_scale_factor_sigma_ppm = 300;
    c.prior_misalignment_sigma_arcsec = 300;
    return c;
  }();

  void Check() const;
};

// The attitude's trust at a moment (OnlineFusion::Status), in order of severity: the worst of a run is
// the maximum, and the CSV status_code is the enumerator's value (0 ok, 1 degraded, 2 failed).
enum class FusionStatus { kOk = 0, kDegraded = 1, kFailed = 2 };
const char* FusionStatusName(FusionStatus s);  // "ok", "degraded", "failed"
inline std::ostream& operator<<(std::ostream& os, FusionStatus v) { return os << FusionStatusName(v); }

// A whole fusion run: "fused" (the attitude trustworthy throughout), "degraded" or "failed" (some of
// the time: see status_s and each sample's status; online_fusion.h), or "no_star_data" (nothing to
// start from).
enum class FuseStatus { kFused, kDegraded, kFailed, kNoStarData };
const char* FuseStatusName(FuseStatus s);
inline std::ostream& operator<<(std::ostream& os, FuseStatus v) { return os << FuseStatusName(v); }

struct FusedSample {
  double t_s = 0;
  Quat q_inertial_from_body = Quat::Identity();
  Vec3 sigma_rad = Vec3::Zero();  // 1 sigma attitude error about body x, y, z
  Vec3 bias_dph = Vec3::Zero();
  Vec3 bias_sigma_dph = Vec3::Zero();
  // The body rate of the gyro interval ending at t_s, bias removed (rad/s): what the CCSDS messages
  // carry as angular velocity.
  Vec3 w_body_rad_s = Vec3::Zero();
  FusionStatus status = FusionStatus::kOk;
};

struct FuseResult {
  FuseStatus status = FuseStatus::kNoStarData;
  std::string message;
  std::vector<FusedSample> samples;
  Vec3 bias_dph = Vec3::Zero(), bias_sigma_dph = Vec3::Zero();
  std::vector<FaultEvent> faults;
  std::map<std::string, double> status_s;  // time (s) spent ok, degraded, failed
  std::vector<int> gyros_in_use;           // 1-based, at the end
  long n_gyro_samples = 0, n_st_used = 0, n_st_rejected = 0;
  double longest_st_gap_s = 0;
  double st_residual_rms_arcsec = 0;  // accepted pre-update residuals
  double seconds_elapsed = 0;
  // The gyro noise the filter used (docs/inertial.md): arw_deg_per_sqrt_h, bias_instability_dph,
  // rrw_dph_per_sqrt_h, init_bias_sigma_dph of the first gyro (body axis x), the bias walk they map to,
  // and per_gyro; the caller adds "source".
  Json noise = Json::object();

  Json ToJson() const;
};

// Fuses a gyro log with a star-tracker log. With body rates (log.body_rates) `unit` gives only the
// noise figures of an equivalent orthogonal triad: a 3-gyro unit those of body x, y, z in turn, any
// other unit its first gyro's on every axis. Starts at the first star sample. Throws
// InputError when the log's gyro count does not match the unit.
FuseResult Fuse(const GyroLog& gyro, const StarTrackerLog& st, const GyroUnit& unit, const FuseOptions& options);

// Gyro noise from `ssiu allan --json` output (calibration/allan_io.h AllanReportJson): one report (one
// gyro) or an array of reports (one per axis or gyro). Per report, the terms arw_deg_per_sqrt_h,
// bias_instability_dph and rrw_deg_per_h_per_sqrt_h ({"value", "significant"}) give the error model's
// ARW, flicker floor and RRW; a term the fit did not find significant counts as 0 (docs/inertial.md).
// InputError naming the file and key for a missing or ill-typed field, a negative or non-finite value,
// or no significant angle random walk (the filter needs white rate noise).
std::vector<GyroErrorModel> ReadAllanNoise(const std::string& path);

// The MEKF's noise model for the gyros `solver` uses: white rate noise and bias walk of the
// least-squares body rate (rad^2/s, rad^2/s^3), plus a bias-walk floor (deg/h per sqrt(h)).
MekfNoise FuseNoiseModel(const GyroUnit& unit, const RateSolver& solver, double floor_dph_per_sqrt_h);

// Gyro noise given for a fuse run beside (or instead of) a unit file: `ssiu fuse --noise` and the
// noise flags, the Python module's keyword arguments. Every figure given is checked by
// FuseUnitForLog (InputError naming the field).
struct FuseNoiseGiven {
  std::string noise_file;                      // `ssiu allan --json` output; "" = none
  std::optional<double> arw_deg_per_sqrt_h;    // every gyro/axis; must be > 0
  std::optional<double> bias_instability_dph;  // must be >= 0
  std::optional<double> rrw_dph_per_sqrt_h;    // must be >= 0
  bool init_bias_sigma_given = false;          // FuseOptions::init_bias_sigma_dph was set by the user
  bool any() const { return !noise_file.empty() || arw_deg_per_sqrt_h || bias_instability_dph || rrw_dph_per_sqrt_h; }
};

// The unit a fuse run uses for `log` (read from `log_name`): `unit_path`'s unit.json, else the
// default four-FOG unit (an ideal triad when a body-rate log has its own noise). The log must have
// as many g*_dph columns as the unit has gyros. Its noise, in order of precedence: the given figures,
// the noise file (one report, or one per gyro/axis), the unit (docs/inertial.md "How a log gets its
// noise"). `noise_source` gets flags, noise_file, unit_file or default_unit. InputError naming the
// file or field.
GyroUnit FuseUnitForLog(const GyroLog& log, const std::string& log_name, const std::string& unit_path,
                        const FuseNoiseGiven& noise, std::string* noise_source);

// Writes t_s,qw,qx,qy,qz,sigma_x_arcsec,sigma_y_arcsec,sigma_z_arcsec,bx_dph,by_dph,bz_dph,status_code
// (0 ok, 1 degraded, 2 failed).
void WriteFusedAttitude(const std::string& path, const FuseResult& result);

}  // namespace ssiu
