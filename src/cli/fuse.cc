// `ssiu fuse`: star-tracker quaternions + gyro log -> attitude, gyro biases and fault events (MEKF).
#include <cmath>
#include <iostream>
#include <memory>
#include <vector>

#include "cli/command.h"
#include "core/error.h"
#include "inertial/fuse.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string gyro, st, unit, json, out, noise;
  FuseOptions fuse;
  bool no_fdi = false;
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

// The gyro noise the filter uses, in order of precedence: flags, --noise FILE, --unit, the default
// four-FOG unit (docs/inertial.md "How a log gets its noise"). Sets `unit`'s error models' noise terms
// and returns the source.
std::string ApplyNoise(const Opts& o, const GyroLog& log, GyroUnit* unit) {
  std::string source = o.unit.empty() ? "default_unit" : "unit_file";
  if (log.body_rates && o.unit.empty() && (!o.noise.empty() || o.arw_given ||
                                           o.bias_instability_given || o.rrw_given)) {
    *unit = OrthogonalTriad();  // body rates with their own noise: an ideal triad carries it
  }
  const int n = log.body_rates ? (unit->size() == 3 ? 3 : 1) : unit->size();
  if (!o.noise.empty()) {
    const std::vector<GyroErrorModel> m = ReadAllanNoise(o.noise);
    if (m.size() != 1 && static_cast<int>(m.size()) != n) {
      throw InputError(o.noise, "has " + std::to_string(m.size()) + " reports: give one, or one per " +
                                    (log.body_rates ? std::string("body axis (3)") : "gyro (" + std::to_string(n) + ")"));
    }
    for (int i = 0; i < unit->size(); ++i) {
      GyroErrorModel& g = unit->gyros[i];
      const GyroErrorModel& s = m[m.size() == 1 ? 0 : std::min<size_t>(i, m.size() - 1)];
      g.arw_deg_per_sqrt_h = s.arw_deg_per_sqrt_h;
      g.bias_instability_dph = s.bias_instability_dph;
      g.rrw_dph_per_sqrt_h = s.rrw_dph_per_sqrt_h;
    }
    source = "noise_file";
  }
  auto flag = [&](bool given, double v, const char* name, bool positive, double GyroErrorModel::*field) {
    if (given) {
      CheckFlag(v, name, positive);
      for (auto& g : unit->gyros) g.*field = v;
      source = "flags";
    }
  };
  flag(o.arw_given, o.arw, "--arw-deg-per-sqrt-h", true, &GyroErrorModel::arw_deg_per_sqrt_h);
  flag(o.bias_instability_given, o.bias_instability, "--bias-instability-dph", false, &GyroErrorModel::bias_instability_dph);
  flag(o.rrw_given, o.rrw, "--rrw-dph-per-sqrt-h", false, &GyroErrorModel::rrw_dph_per_sqrt_h);
  if (o.init_bias_sigma_given) {
    CheckFlag(o.fuse.init_bias_sigma_dph, "--init-bias-sigma-dph", true);
    source = "flags";
  }
  return source;
}

void Run(Opts o) {
  GyroUnit unit;
  GyroLog log;
  if (!o.unit.empty()) {
    unit = LoadGyroUnit(o.unit);
    // Read every g*_dph column and compare the count: reading only the unit's first N ignored a
    // log's extra gyros (a 3-gyro unit on a four-FOG log dropped g4 without a word).
    log = ReadGyroLog(o.gyro, 0);
    const int n_log = static_cast<int>(log.rates_dph.front().size());
    if (!log.body_rates && n_log != unit.size()) {
      throw InputError(o.gyro, "has g1_dph..g" + std::to_string(n_log) + "_dph columns for " + std::to_string(n_log) +
                                   " gyros but " + o.unit + " describes " + std::to_string(unit.size()));
    }
  } else {
    log = ReadGyroLog(o.gyro, 0);
    unit = DefaultFourFogUnit();
    if (!log.body_rates && log.rates_dph.front().size() != 4) {
      throw InputError(o.gyro, "has g1_dph..gN_dph columns for " + std::to_string(log.rates_dph.front().size()) +
                                   " gyros: give --unit unit.json");
    }
  }
  const std::string noise_source = ApplyNoise(o, log, &unit);
  const StarTrackerLog st = ReadStarTrackerLog(o.st);
  o.fuse.fdi = !o.no_fdi;
  FuseResult r = Fuse(log, st, unit, o.fuse);
  r.noise["source"] = noise_source;
  if (!o.noise.empty()) r.noise["noise_file"] = o.noise;
  if (!o.json.empty()) WriteJsonFile(o.json, r.ToJson());
  if (!o.out.empty()) WriteFusedAttitude(o.out, r);
  std::cerr << "fuse: noise (" << noise_source << "): ARW " << r.noise.value("arw_deg_per_sqrt_h", 0.0)
            << " deg/sqrt(h), bias instability " << r.noise.value("bias_instability_dph", 0.0) << " deg/h, RRW "
            << r.noise.value("rrw_dph_per_sqrt_h", 0.0) << " deg/h/sqrt(h) -> bias walk "
            << r.noise.value("bias_walk_dph_per_sqrt_h", 0.0) << " deg/h/sqrt(h), initial bias sigma "
            << o.fuse.init_bias_sigma_dph << " deg/h\n";
  std::cerr << "fuse: " << r.status << ": " << r.message << "; bias [" << r.bias_dph.x() << ", " << r.bias_dph.y()
            << ", " << r.bias_dph.z() << "] deg/h\n";
}

}  // namespace
}  // namespace ssiu::cli

SSIU_REGISTER_COMMAND(fuse, [](CLI::App& root) {
  using namespace ssiu::cli;
  CLI::App* cmd = root.add_subcommand(
      "fuse", "Fuse gyro rates with star-tracker attitudes (multiplicative EKF): attitude, gyro biases, gyro faults");
  auto o = std::make_shared<Opts>();
  cmd->add_option("--gyro", o->gyro, "Gyro log: t_s + wx_dph,wy_dph,wz_dph or g1_dph..gN_dph")->required();
  cmd->add_option("--st", o->st, "Star-tracker log: t_s,qw,qx,qy,qz [,sigma_cross_arcsec,sigma_roll_arcsec]")
      ->required();
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
  cmd->add_option("--rrw-dph-per-sqrt-h", o->rrw, "Rate random walk of every gyro/axis, deg/h/sqrt(h) (overrides --noise)")
      ->each([o](const std::string&) { o->rrw_given = true; });
  cmd->add_option("--init-bias-sigma-dph", o->fuse.init_bias_sigma_dph, "Prior 1 sigma of each body-axis bias (default 10)")
      ->each([o](const std::string&) { o->init_bias_sigma_given = true; });
  cmd->add_option("--json", o->json, "Result JSON (bias_dph, bias_sigma_dph, faults, ...), - for stdout");
  cmd->add_option("--out", o->out, "Attitude CSV: t_s,qw,qx,qy,qz,sigma_{x,y,z}_arcsec,b{x,y,z}_dph");
  cmd->add_option("--st-sigma-cross-arcsec", o->fuse.st_sigma_cross_arcsec, "Star-tracker cross-boresight noise");
  cmd->add_option("--st-sigma-roll-arcsec", o->fuse.st_sigma_roll_arcsec, "Star-tracker roll noise");
  cmd->add_option("--output-every", o->fuse.output_every, "Write every n-th gyro sample");
  cmd->add_flag("--no-fdi", o->no_fdi, "Switch off gyro fault detection and isolation");
  cmd->callback([o] { Run(*o); });
});
