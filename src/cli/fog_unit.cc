// `ssiu fog unit-calibrate`: the four-FOG unit calibrated as a whole on the bench
// (docs/fog-calibration.md, "Unit calibration").
#include "calibration/fog_unit.h"

#include <iostream>
#include <memory>
#include <sstream>

#include "cli/command.h"
#include "core/json.h"

namespace {

struct UnitCalOpts {
  std::vector<std::string> logs;
  std::string unit, out, json;
  ssiu::UnitCalibrationOptions fit;
};

void RunUnitCalibrate(const UnitCalOpts& o) {
  const ssiu::GyroUnit nominal = ssiu::LoadGyroUnit(o.unit);
  std::vector<ssiu::UnitBenchLog> logs;
  for (const auto& p : o.logs) logs.push_back(ssiu::ReadUnitBenchLog(p, nominal.size()));
  const ssiu::UnitCalibrationResult r = ssiu::CalibrateUnit(logs, nominal, o.fit);
  ssiu::WriteJsonFile(o.out, ssiu::GyroUnitToJson(r.unit));
  if (!o.json.empty()) ssiu::WriteJsonFile(o.json, ssiu::UnitCalibrationToJson(r, o.fit));
  std::ostringstream s;
  for (size_t i = 0; i < r.gyros.size(); ++i) {
    const auto& g = r.gyros[i];
    s << "fog unit-calibrate: gyro " << i + 1 << ": bias " << g.bias_dph << "+-" << std::sqrt(g.cov(0, 0))
      << " deg/h, scale " << g.scale_factor_ppm << "+-" << std::sqrt(g.cov(1, 1)) << " ppm, misalignment ["
      << g.misalignment_arcsec[0] << ", " << g.misalignment_arcsec[1] << "]+-[" << std::sqrt(g.cov(2, 2)) << ", "
      << std::sqrt(g.cov(3, 3)) << "] arcsec";
    for (const auto& t : g.terms) {
      if (t.optional && t.kept) s << ", " << t.name << " " << t.estimate << "+-" << t.sigma << " " << t.unit;
    }
    s << "\n";
  }
  s << "fog unit-calibrate: " << r.n_bins << " bins from " << r.n_logs << " log(s), " << r.n_steps << " steps; wrote "
    << o.out << "\n";
  std::cerr << s.str();
}

}  // namespace

SSIU_REGISTER_COMMAND(fog_unit_calibrate, [](CLI::App& root) {
  auto* fog = ssiu::cli::GetOrAddSubcommand(root, "fog", "FOG bench calibration (thermal drift, magnetic sensitivity)");
  auto* cmd = fog->add_subcommand(
      "unit-calibrate", "Fit each gyro's bias, scale factor and sensing axis from multi-position and rate-table logs");
  auto o = std::make_shared<UnitCalOpts>();
  cmd->add_option("logs", o->logs, "Bench logs t_s,g1_dph..gN_dph,ref_x_dph,ref_y_dph,ref_z_dph[,temp_c]")->required();
  cmd->add_option("--unit", o->unit, "Nominal unit.json (axes, noise model)")->required();
  cmd->add_option("--out", o->out, "Calibrated unit.json (for fuse --unit, run, the processor)")->required();
  cmd->add_option("--json", o->json, "Report JSON (sigmas, covariances, term tests), - for stdout");
  cmd->add_option("--bin-s", o->fit.bin_s, "Averaging bin within a step, s")->capture_default_str();
  cmd->add_option("--settle-s", o->fit.settle_s, "Dropped after each reference step, s")->capture_default_str();
  cmd->add_option("--step-dph", o->fit.step_dph, "Reference change between samples that starts a step, deg/h")
      ->capture_default_str();
  cmd->add_option("--temp-ref-c", o->fit.temp_ref_c, "Temperature the bias refers to (default: the logs' mean), C");
  cmd->add_option("--rate-window-s", o->fit.rate.window_s, "Window of the local cubic fit for T and dT/dt, s")
      ->capture_default_str();
  cmd->add_flag("!--white-only", o->fit.wander_from_unit,
                "Ignore the nominal unit's bias wander in the noise model (for comparison)");
  cmd->callback([o] { RunUnitCalibrate(*o); });
});
