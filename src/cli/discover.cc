// `ssiu discover gyro LOG.csv [LOG2.csv ...] --json OUT` and `ssiu discover frames FRAME... --camera
// CAM.json --json OUT`: model discrepancy analysis (docs/discrepancy.md). The library does the work
// (analysis/discover_gyro.h, analysis/discover_frames.h); this file parses flags and writes JSON.
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "analysis/discover_gyro.h"
#include "cli/command.h"
#include "core/json.h"

namespace {

struct GyroOpts {
  std::vector<std::string> logs;
  std::string json;
  ssiu::GyroDiscoverOptions opt;
};

}  // namespace

SSIU_REGISTER_COMMAND(discover_gyro, [](CLI::App& root) {
  auto* discover = ssiu::cli::GetOrAddSubcommand(root, "discover", "Find what the model gets wrong in measured data");
  auto* cmd = discover->add_subcommand(
      "gyro", "Test candidate causes (temperature, magnetic_field, scale_factor, ...) against the base gyro model");
  auto o = std::make_shared<GyroOpts>();
  cmd->add_option("logs", o->logs, "Bench logs t_s,w_dph,ref_dph,temp_c[,azimuth_deg]")->required();
  cmd->add_option("--json", o->json, "Output JSON, - for stdout");
  cmd->add_option("--alpha", o->opt.alpha, "Family-wise false-alarm probability")->capture_default_str();
  cmd->add_option("--max-bins", o->opt.max_bins_per_log, "Bins per log at most")->capture_default_str();
  cmd->add_option("--wander-tau-max-s", o->opt.wander_tau_max_s, "Longest correlation time of the base wander, s")
      ->capture_default_str();
  cmd->add_option("--cv-blocks", o->opt.cv_blocks, "Blocks per log for the cross-validated gain")->capture_default_str();
  cmd->callback([o] {
    std::vector<ssiu::GyroBenchLog> logs;
    for (const auto& f : o->logs) logs.push_back(ssiu::ReadGyroBenchLog(f));
    const ssiu::GyroDiscovery d = ssiu::DiscoverGyro(logs, o->opt);
    std::cerr << "discover gyro: cause " << d.cause;
    for (const auto& [k, v] : d.parameters) std::cerr << " " << k << "=" << v << "+-" << d.sigmas.at(k);
    std::cerr << "; held-out rms " << d.rms_before_dph << " -> " << d.rms_after_dph << " deg/h (gain " << d.gain
              << ")\n";
    if (!o->json.empty()) ssiu::WriteJsonFile(o->json, ssiu::GyroDiscoveryToJson(d));
  });
});
