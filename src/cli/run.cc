// `ssiu run [--config SSIU.json] [--json OUT] [--out DIR [--write-frames]]`: the whole unit on a
// simulated mission (sim/mission.h): frames of 1-3 heads and four-FOG logs -> detect -> solve -> fuse,
// scored against the truth. Without --config the built-in default (a 120 s slew, two heads). With
// --write-frames DIR also gets what the flight interface needs to replay the mission
// (examples/flight, docs/flight.md): every frame (DIR/frames/*.pgm), the unit's flight.cfg and the
// catalog blob (DIR/catalog/catalog.bin).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "cli/adm_flags.h"
#include "cli/command.h"
#include "core/catalog.h"
#include "core/error.h"
#include "core/json.h"
#include "core/output.h"
#include "flight/flight_config.h"
#include "identify/star_catalog.h"
#include "inertial/fuse_adm.h"
#include "sim/mission.h"

namespace {
struct RunOpts {
  std::string config, json, out;
  bool print_config = false, write_frames = false;
  ssiu::cli::AdmFlags adm;
};

// The fused attitude of the run as a CCSDS history: the processor's noise (its first gyro, as `ssiu
// fuse` states it), each head at the frame rate with its mean 1-sigma, the gyros at their rate.
ssiu::AttitudeHistory RunHistory(const ssiu::MissionConfig& config, const ssiu::MissionResult& r) {
  const ssiu::GyroUnit unit = ssiu::WithUnitKnowledge(config).unit;
  const auto& g = unit.gyros.at(0);
  const ssiu::Json noise = {{"arw_deg_per_sqrt_h", g.arw_deg_per_sqrt_h},
                            {"bias_walk_dph_per_sqrt_h", g.BiasDriftDphPerSqrtS() * 60.0}};
  std::vector<ssiu::AdmSensor> sensors;
  for (size_t h = 0; h < r.heads.size(); ++h) {
    sensors.push_back(ssiu::StarTrackerSensor(static_cast<int>(h) + 1, static_cast<int>(h) + 1,
                                              r.heads[h].mean_sigma_cross_arcsec, r.heads[h].mean_sigma_roll_arcsec,
                                              config.frame_rate_hz));
  }
  sensors.push_back(ssiu::GyroSensor(static_cast<int>(sensors.size()) + 1, g.arw_deg_per_sqrt_h, unit.rate_hz));
  ssiu::AttitudeHistory h = ssiu::FusedAttitudeHistory(r.history, config.start_utc, noise, sensors);
  h.basis = "SIMULATED";
  return h;
}

// DIR/catalog (head 1's catalog: the flight interface takes one blob for all heads) and DIR/flight.cfg.
void WriteFlightFiles(const ssiu::MissionConfig& config, const std::string& dir) {
  const ssiu::StarIdentifier id = ssiu::MakeIdentifierForCamera("", config.heads[0].camera, 0.0);
  ssiu::SaveSolverCatalog(id.catalog(), dir + "/catalog");
  const ssiu::CatalogDirState state = ssiu::CheckCatalogDir(dir + "/catalog");
  if (state != ssiu::CatalogDirState::kOk) throw ssiu::InputError(dir + "/catalog", "catalog not written");
  const std::string meta_path = dir + "/catalog/meta.json";
  const ssiu::Json meta = ssiu::ReadJsonFile(meta_path);
  const ssiu::MissionConfig known = ssiu::WithUnitKnowledge(config);  // as RunMission's processor has it
  ssiu_flight_config c =
      ssiu::FlightConfigFor(known.heads, known.unit, known.processor, known.start_utc, known.velocity_kms);
  c.catalog_crc32 = static_cast<uint32_t>(ssiu::JsonInt(meta, "catalog_bin_crc32", 1, 0xffffffffLL, meta_path));
  ssiu::WriteFileAtomic(dir + "/flight.cfg", ssiu::FlightConfigText(c));
}
}  // namespace

SSIU_REGISTER_COMMAND(run, [](CLI::App& root) {
  CLI::App* cmd = root.add_subcommand(
      "run", "Simulate a short SSIU mission and process it as the unit would; attitude accuracy against the truth");
  auto opts = std::make_shared<RunOpts>();
  cmd->add_option("--config", opts->config, "Mission config SSIU.json (docs/inertial.md); default: built in");
  cmd->add_option("--json", opts->json, "Write the figures as JSON (- for stdout)");
  cmd->add_option("--out", opts->out, "Write attitude.csv, frames.csv, gyro.csv, truth.csv, first frames here");
  ssiu::cli::AddAdmFlags(cmd, &opts->adm, "the fused attitude and rate",
                         "gyro bias, covariance, EKF and its noise, sensors");
  cmd->add_flag("--print-config", opts->print_config, "Print the mission config in use as JSON and exit");
  cmd->add_flag("--write-frames", opts->write_frames,
                "With --out: also every frame (frames/*.pgm), flight.cfg and catalog/ for examples/flight");
  cmd->callback([opts] {
    const ssiu::MissionConfig config =
        opts->config.empty() ? ssiu::DefaultMissionConfig() : ssiu::LoadMissionConfig(opts->config);
    if (opts->print_config) {
      ssiu::WriteJsonFile("-", ssiu::MissionConfigToJson(config));
      return;
    }
    if (opts->write_frames && opts->out.empty()) throw ssiu::InputError("--write-frames", "needs --out DIR");
    if (opts->write_frames) {  // a unit the flight interface cannot carry is refused before the mission runs
      const ssiu::MissionConfig known = ssiu::WithUnitKnowledge(config);
      try {
        ssiu::FlightSetupFrom(
            ssiu::FlightConfigFor(known.heads, known.unit, known.processor, known.start_utc, known.velocity_kms));
      } catch (const ssiu::InputError& e) {
        throw ssiu::InputError(opts->config.empty() ? "--write-frames" : opts->config,
                               std::string(e.what()) + " (the flight interface, --write-frames)");
      }
    }
    if (!opts->out.empty()) {  // before the mission runs, and as bad input (not a filesystem exception)
      std::error_code ec;
      std::filesystem::create_directories(opts->out, ec);
      if (!std::filesystem::is_directory(opts->out, ec))
        throw ssiu::InputError(opts->out, "cannot create output directory");
    }
    std::printf("ssiu run: %s, %.0f s, %zu head(s), frames at %.3g Hz, %d gyros at %.0f Hz, seed %llu\n",
                opts->config.empty() ? "built-in default mission" : opts->config.c_str(), config.duration_s,
                config.heads.size(), config.frame_rate_hz, config.unit.size(), config.unit.rate_hz,
                static_cast<unsigned long long>(config.seed));
    std::fflush(stdout);
    const ssiu::MissionResult r = ssiu::RunMission(config, ssiu::LoadXplanetBsc(ssiu::DefaultBscPath()), opts->out,
                                                   opts->write_frames, opts->adm.given());
    if (opts->adm.given()) ssiu::cli::WriteAdmOutputs(opts->adm, RunHistory(config, r));
    if (opts->write_frames) WriteFlightFiles(config, opts->out);
    std::fputs(r.Text().c_str(), stdout);
    if (!opts->json.empty()) {
      ssiu::Json j = r.ToJson();
      j["config"] = ssiu::MissionConfigToJson(config);
      ssiu::WriteJsonFile(opts->json, j);
    }
  });
});
