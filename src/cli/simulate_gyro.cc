// `ssiu simulate gyro`: a four-FOG (or any 3..6 gyro) log with truth and a star-tracker log.
#include <filesystem>
#include <iostream>
#include <memory>

#include "cli/command.h"
#include "core/error.h"
#include "sim/gyro_sim.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string unit, profile = "slew", out;
  double duration_s = 3600;
  bool duration_given = false;
  uint64_t seed = 1;
};

void Run(const Opts& o) {
  const GyroUnit unit = o.unit.empty() ? DefaultFourFogUnit() : LoadGyroUnit(o.unit);
  // A profile is a JSON file, or the name of a built-in one with default settings.
  MotionProfile profile;
  if (o.profile == "static" || o.profile == "slew" || o.profile == "sine" || o.profile == "temperature" ||
      o.profile == "bench") {
    profile = MotionProfileFromJson(Json{{"type", o.profile}}, o.profile);
  } else {
    profile = LoadMotionProfile(o.profile);
  }
  profile.Check(o.profile, unit.size());  // here, to name the file (SimulateGyro checks it again)
  GyroSimOptions so;
  // A bench campaign lasts as long as its segments unless told otherwise.
  so.duration_s = profile.type == "bench" && !o.duration_given ? BenchDurationS(profile) : o.duration_s;
  so.seed = o.seed;
  if (!(so.duration_s > 0) || so.duration_s * unit.rate_hz > 5e7) {
    throw InputError("simulate gyro", "--duration-s must be positive and give at most 5e7 samples");
  }
  const GyroSimulation sim = SimulateGyro(unit, profile, so);
  WriteGyroSimulation(o.out, sim, unit);
  std::cout << o.out << ": " << sim.t_s.size() << " samples of " << unit.size() << " gyros at " << unit.rate_hz
            << " Hz, " << sim.st_t_s.size() << " star-tracker samples (" << profile.type << " profile)\n";
}

}  // namespace
}  // namespace ssiu::cli

SSIU_REGISTER_COMMAND(simulate_gyro, [](CLI::App& root) {
  using namespace ssiu::cli;
  CLI::App* sim = GetOrAddSubcommand(root, "simulate", "Simulate data (star frames, gyro logs)");
  CLI::App* cmd = sim->add_subcommand(
      "gyro",
      "Simulate a redundant FOG unit: DIR/gyro.csv, truth.csv, rates.csv (true rates and biases), st.csv, unit.json");
  auto o = std::make_shared<Opts>();
  cmd->add_option("--unit", o->unit, "unit.json (default: four navigation-grade FOGs, 3 orthogonal + 1 skewed)");
  cmd->add_option("--profile", o->profile,
                  "PROFILE.json, or one of static, slew, sine, temperature, bench (built-in defaults; bench: the unit "
                  "calibration campaign of docs/fog-calibration.md); see docs/inertial.md");
  cmd->add_option("--duration-s", o->duration_s, "Duration (s); a bench profile: default its segments' total");
  cmd->add_option("--seed", o->seed, "Random seed");
  cmd->add_option("--out", o->out, "Output directory")->required();
  cmd->callback([o, cmd] {
    o->duration_given = cmd->count("--duration-s") > 0;
    Run(*o);
  });
});
