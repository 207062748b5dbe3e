// `ssiu simulate fog-thermal|fog-turntable`: the simulated bench campaigns of docs/fog-calibration.md.
#include <memory>
#include <sstream>

#include "cli/command.h"
#include "core/error.h"
#include "sim/fog_bench_sim.h"

namespace {

ssiu::MagneticSensitivity ParseSensitivity(const std::string& s, const std::string& flag) {
  ssiu::MagneticSensitivity m;
  if (s.empty()) return m;
  std::istringstream in(s);
  char c1 = 0, c2 = 0;
  if (!(in >> m.along_dph_per_ut >> c1 >> m.across_dph_per_ut >> c2 >> m.vertical_dph_per_ut) || c1 != ',' ||
      c2 != ',') {
    throw ssiu::InputError(flag, "expected ALONG,ACROSS,VERTICAL in deg/h per microtesla");
  }
  return m;
}

struct TurntableCliOpts {
  ssiu::TurntableOptions sim;
  std::string out, mag_x, mag_y;
};

}  // namespace

SSIU_REGISTER_COMMAND(fog_simulate, [](CLI::App& root) {
  auto* sim = ssiu::cli::GetOrAddSubcommand(root, "simulate", "Simulate data");
  {
    auto* cmd = sim->add_subcommand("fog-thermal", "A 700-minute thermal bench run of one FOG (campaign drift model)");
    auto o = std::make_shared<ssiu::ThermalBenchOptions>();
    auto out = std::make_shared<std::string>();
    o->drift = ssiu::CampaignDriftModel();
    cmd->add_option("--out", *out, "Output CSV")->required();
    cmd->add_option("--seed", o->seed, "Random seed (each seed gives another temperature programme)")
        ->capture_default_str();
    cmd->add_option("--duration-s", o->duration_s, "Run length, s")->capture_default_str();
    cmd->add_option("--dt-s", o->dt_s, "Sample interval, s")->capture_default_str();
    cmd->add_option("--white-noise-dph", o->white_noise_dph, "Per-sample white noise, deg/h")->capture_default_str();
    cmd->add_option("--wander-dph", o->wander_sigma_dph, "Bias wander sigma, deg/h")->capture_default_str();
    cmd->callback([o, out] { ssiu::WriteThermalRunCsv(*out, ssiu::SimulateThermalRun(*o)); });
  }
  {
    auto* cmd = sim->add_subcommand("fog-turntable", "A 25-azimuth turntable log of FOGX/FOGY");
    auto o = std::make_shared<TurntableCliOpts>();
    cmd->add_option("--out", o->out, "Output CSV")->required();
    cmd->add_option("--seed", o->sim.seed, "Random seed")->capture_default_str();
    cmd->add_option("--positions", o->sim.positions, "Number of azimuths")->capture_default_str();
    cmd->add_option("--dpsi0-deg", o->sim.dpsi0_deg, "Initial azimuth trim error, deg")->capture_default_str();
    cmd->add_option("--latitude-deg", o->sim.latitude_deg, "Bench latitude")->capture_default_str();
    cmd->add_option("--mag-x", o->mag_x, "FOGX sensitivities ALONG,ACROSS,VERTICAL, deg/h per uT");
    cmd->add_option("--mag-y", o->mag_y, "FOGY sensitivities ALONG,ACROSS,VERTICAL, deg/h per uT");
    cmd->callback([o] {
      ssiu::TurntableOptions s = o->sim;
      s.fog_x = ParseSensitivity(o->mag_x, "--mag-x");
      s.fog_y = ParseSensitivity(o->mag_y, "--mag-y");
      ssiu::WriteTurntableCsv(o->out, ssiu::SimulateTurntable(s));
    });
  }
});
