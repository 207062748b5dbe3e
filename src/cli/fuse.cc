// `ssiu fuse`: star-tracker quaternions + gyro log -> attitude, gyro biases and fault events (MEKF).
#include <iostream>
#include <memory>

#include "cli/command.h"
#include "core/error.h"
#include "inertial/fuse.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string gyro, st, unit, json, out;
  FuseOptions fuse;
  bool no_fdi = false;
};

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
  const StarTrackerLog st = ReadStarTrackerLog(o.st);
  o.fuse.fdi = !o.no_fdi;
  const FuseResult r = Fuse(log, st, unit, o.fuse);
  if (!o.json.empty()) WriteJsonFile(o.json, r.ToJson());
  if (!o.out.empty()) WriteFusedAttitude(o.out, r);
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
  cmd->add_option("--unit", o->unit, "unit.json for g*_dph logs (default: the four-FOG unit)");
  cmd->add_option("--json", o->json, "Result JSON (bias_dph, bias_sigma_dph, faults, ...), - for stdout");
  cmd->add_option("--out", o->out, "Attitude CSV: t_s,qw,qx,qy,qz,sigma_{x,y,z}_arcsec,b{x,y,z}_dph");
  cmd->add_option("--st-sigma-cross-arcsec", o->fuse.st_sigma_cross_arcsec, "Star-tracker cross-boresight noise");
  cmd->add_option("--st-sigma-roll-arcsec", o->fuse.st_sigma_roll_arcsec, "Star-tracker roll noise");
  cmd->add_option("--output-every", o->fuse.output_every, "Write every n-th gyro sample");
  cmd->add_flag("--no-fdi", o->no_fdi, "Switch off gyro fault detection and isolation");
  cmd->callback([o] { Run(*o); });
});
