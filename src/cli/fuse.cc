// `ssiu fuse`: star-tracker quaternions + gyro log -> attitude, gyro biases and fault events (MEKF).
#include "inertial/fuse.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>
#include <vector>

#include "cli/adm_flags.h"
#include "cli/command.h"
#include "core/error.h"
#include "inertial/fuse_adm.h"
#include "inertial/unit_inflight.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string gyro, st, unit, json, out, noise, epoch_utc;
  AdmFlags adm;
  FuseOptions fuse;
  bool no_fdi = false;
  bool calibrate_unit = false;  // in-flight calibration of scale factors and axes (off by default)
  InflightCalOptions inflight;
  // Noise flags (override --noise and the unit) and whether each was given.
  double arw = 0, bias_instability = 0, rrw = 0;
  bool arw_given = false, bias_instability_given = false, rrw_given = false, init_bias_sigma_given = false;
};

// A given flag must be a finite number >= 0 (> 0 where `positive`).
void CheckFlag(double v, const char* flag, bool positive) {
  if (!std::isfinite(v) || v < 0 || (positive && v == 0)) {
    throw InputError(flag, positive ? "must be a finite number > 0" : "must be a finite number >= 0");
  }
}

// The AD section's sensors: the star tracker (its noise: the log's median sigmas, else the options')
// and the gyros (the angle noise of one sample, SIGMA_V sqrt(dt)), each at its median rate.
std::vector<AdmSensor> FuseSensors(const StarTrackerLog& st, const GyroLog& gyro, const FuseResult& r,
                                   const FuseOptions& options) {
  auto median = [](std::vector<double> v, double fallback) {
    if (v.empty()) return fallback;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  return {StarTrackerSensor(1, 1, median(st.sigma_cross_arcsec, options.st_sigma_cross_arcsec),
                            median(st.sigma_roll_arcsec, options.st_sigma_roll_arcsec), MedianRateHz(st.t_s)),
          GyroSensor(2, r.noise.value("arw_deg_per_sqrt_h", 0.0), MedianRateHz(gyro.t_s))};
}

void Run(Opts o) {
  // Flags are checked here so that the message names the flag; the library checks the figures too.
  FuseNoiseGiven given;
  given.noise_file = o.noise;
  if (o.arw_given) CheckFlag(o.arw, "--arw-deg-per-sqrt-h", true), given.arw_deg_per_sqrt_h = o.arw;
  if (o.bias_instability_given)
    CheckFlag(o.bias_instability, "--bias-instability-dph", false), given.bias_instability_dph = o.bias_instability;
  if (o.rrw_given) CheckFlag(o.rrw, "--rrw-dph-per-sqrt-h", false), given.rrw_dph_per_sqrt_h = o.rrw;
  if (o.init_bias_sigma_given) CheckFlag(o.fuse.init_bias_sigma_dph, "--init-bias-sigma-dph", true);
  given.init_bias_sigma_given = o.init_bias_sigma_given;
  const GyroLog log = ReadGyroLog(o.gyro, 0);
  std::string noise_source;
  const GyroUnit unit = FuseUnitForLog(log, o.gyro, o.unit, given, &noise_source);
  const StarTrackerLog st = ReadStarTrackerLog(o.st, o.epoch_utc);
  const std::string epoch_utc = o.epoch_utc.empty() ? st.epoch_utc : o.epoch_utc;
  if (o.adm.given() && epoch_utc.empty())
    throw InputError("--epoch-utc", "--aem/--acm need the UTC of t_s = 0 (a CSV log has no time of day)");
  if (!epoch_utc.empty()) AdmEpoch(epoch_utc, 0.0);  // a bad --epoch-utc is reported before the run
  o.fuse.fdi = !o.no_fdi;
  // In-flight calibration first (a batch over the whole log); the fusion then uses the calibrated unit.
  Json calibration;
  GyroUnit used = unit;
  if (o.calibrate_unit) {
    const InflightCalResult c =
        CalibrateUnitInFlight(log, st, unit, o.fuse.st_sigma_cross_arcsec, o.fuse.st_sigma_roll_arcsec, o.inflight);
    calibration = c.ToJson();
    if (c.ok) used = c.unit;
    std::cerr << "fuse: unit calibration: " << (c.ok ? "fitted" : c.message) << " (" << c.n_windows
              << " star windows)\n";
  }
  FuseResult r = Fuse(log, st, used, o.fuse);
  r.noise["source"] = noise_source;
  if (!o.noise.empty()) r.noise["noise_file"] = o.noise;
  if (!o.json.empty()) {
    Json j = r.ToJson();
    if (o.calibrate_unit) j["unit_calibration"] = calibration;
    WriteJsonFile(o.json, j);
  }
  if (!o.out.empty()) WriteFusedAttitude(o.out, r);
  if (o.adm.given())
    WriteAdmOutputs(o.adm, FusedAttitudeHistory(r.samples, epoch_utc, r.noise, FuseSensors(st, log, r, o.fuse)));
  std::cerr << "fuse: noise (" << noise_source << "): ARW " << r.noise.value("arw_deg_per_sqrt_h", 0.0)
            << " deg/sqrt(h), bias instability " << r.noise.value("bias_instability_dph", 0.0) << " deg/h, RRW "
            << r.noise.value("rrw_dph_per_sqrt_h", 0.0) << " deg/h/sqrt(h) -> bias walk "
            << r.noise.value("bias_walk_dph_per_sqrt_h", 0.0) << " deg/h/sqrt(h), initial bias sigma "
            << o.fuse.init_bias_sigma_dph << " deg/h\n";
  std::cerr << "fuse: " << FuseStatusName(r.status) << ": " << r.message << "; bias [" << r.bias_dph.x() << ", "
            << r.bias_dph.y() << ", " << r.bias_dph.z() << "] deg/h\n";
}

}  // namespace
}  // namespace ssiu::cli

SSIU_REGISTER_COMMAND(fuse, [](CLI::App& root) {
  using namespace ssiu::cli;
  CLI::App* cmd = root.add_subcommand(
      "fuse", "Fuse gyro rates with star-tracker attitudes (multiplicative EKF): attitude, gyro biases, gyro faults");
  auto o = std::make_shared<Opts>();
  cmd->add_option("--gyro", o->gyro, "Gyro log: t_s + wx_dph,wy_dph,wz_dph or g1_dph..gN_dph")->required();
  cmd->add_option("--st", o->st,
                  "Star-tracker log: t_s,qw,qx,qy,qz [,sigma_cross_arcsec,sigma_roll_arcsec], or a CCSDS AEM/ACM "
                  "(KVN or XML; an ACM's ANGLE covariance gives the sigmas)")
      ->required();
  cmd->add_option("--epoch-utc", o->epoch_utc,
                  "UTC (ISO 8601) of t_s = 0: the origin of an AEM/ACM --st's epochs (default: the ACM's EPOCH_TZERO, "
                  "the AEM's first epoch) and of --aem/--acm (needed with a CSV --st)");
  AddAdmFlags(cmd, &o->adm, "the fused attitude and rate", "gyro bias, covariance, EKF and its noise, sensors");
  cmd->add_option("--unit", o->unit,
                  "unit.json for g*_dph logs (default: the four-FOG unit); on a wx_dph log only its noise counts "
                  "(a 3-gyro unit: x, y, z; else its first gyro's on every axis)");
  cmd->add_option("--noise", o->noise,
                  "Gyro noise from `ssiu allan --json` output (one report, or an array: one per axis/gyro); "
                  "significant ARW, bias instability, RRW; overrides the unit's. Without it or the flags a "
                  "body-rate log gets the default unit's noise (ARW 0.01 deg/sqrt(h), bias instability 0.05 deg/h)");
  cmd->add_option("--arw-deg-per-sqrt-h", o->arw, "Angle random walk of every gyro/axis (overrides --noise)")
      ->each([o](const std::string&) { o->arw_given = true; });
  cmd->add_option("--bias-instability-dph", o->bias_instability,
                  "Bias instability (flicker floor) of every gyro/axis, deg/h (overrides --noise)")
      ->each([o](const std::string&) { o->bias_instability_given = true; });
  cmd->add_option("--rrw-dph-per-sqrt-h", o->rrw,
                  "Rate random walk of every gyro/axis, deg/h/sqrt(h) (overrides --noise)")
      ->each([o](const std::string&) { o->rrw_given = true; });
  cmd->add_option("--init-bias-sigma-dph", o->fuse.init_bias_sigma_dph,
                  "Prior 1 sigma of each body-axis bias (default 10)")
      ->each([o](const std::string&) { o->init_bias_sigma_given = true; });
  cmd->add_option("--json", o->json, "Result JSON (bias_dph, bias_sigma_dph, faults, ...), - for stdout");
  cmd->add_option("--out", o->out, "Attitude CSV: t_s,qw,qx,qy,qz,sigma_{x,y,z}_arcsec,b{x,y,z}_dph");
  cmd->add_option("--st-sigma-cross-arcsec", o->fuse.st_sigma_cross_arcsec, "Star-tracker cross-boresight noise");
  cmd->add_option("--st-sigma-roll-arcsec", o->fuse.st_sigma_roll_arcsec, "Star-tracker roll noise");
  cmd->add_option("--output-every", o->fuse.output_every, "Write every n-th gyro sample");
  cmd->add_flag("--no-fdi", o->no_fdi, "Switch off gyro fault detection and isolation");
  cmd->add_flag("--calibrate-unit", o->calibrate_unit,
                "Estimate the gyros' scale factors and axes from the star attitudes first (batch; needs g1..gN and "
                "turns about three axes), then fuse with them; JSON unit_calibration");
  cmd->add_option("--calibration-window-s", o->inflight.window_s, "Star-to-star window of --calibrate-unit, s")
      ->capture_default_str();
  cmd->add_option("--calibration-bias-block-s", o->inflight.bias_block_s,
                  "--calibrate-unit: the bias is constant within blocks of this length, s")
      ->capture_default_str();
  cmd->callback([o] { Run(*o); });
});
