// `ssiu simulate frame`: writes 16-bit PNG frames and a truth JSON per frame; with --scene-csv also a
// centroid list per frame (sim/scene_sim.h: missing stars, centroid noise, false objects), and with
// --centroids-only the centroid lists alone (no rendering).
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>

#include "cli/command.h"
#include "core/astrometry.h"
#include "core/attitude.h"
#include "core/camera.h"
#include "core/catalog.h"
#include "core/error.h"
#include "sim/frame_sim.h"
#include "sim/scene_sim.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string camera, config, out, catalog = DefaultBscPath();
  double ra_deg = NAN, dec_deg = NAN, roll_deg = 0;
  bool scene_csv = false, centroids_only = false;
  SceneSimOptions scene;
  std::vector<int> false_objects;  // N or MIN,MAX
  bool random = false, no_shot_noise = false, no_proper_motion = false, no_aberration = false;
  std::string time;
  uint64_t seed = 1;
  int count = 1;
  std::map<std::string, double> set;  // flag name -> value, only for flags given
};

void Run(const Opts& o, const std::vector<std::pair<std::string, CLI::Option*>>& flags) {
  const Camera cam = o.camera.empty() ? Camera{} : LoadCamera(o.camera);
  FrameSimOptions so = o.config.empty() ? FrameSimOptions{} : FrameSimOptionsFromJson(ReadJsonFile(o.config), o.config);
  if (!o.time.empty()) {  // before the velocity flags, which need it
    ParseUtcIso8601(o.time, "--time");
    so.time_utc = o.time;
  }
  for (const auto& [name, opt] : flags) {
    if (opt->count() > 0) SetFrameSimOption(&so, name, opt->as<double>());
  }
  if (o.no_shot_noise) so.shot_noise = false;
  if (o.no_proper_motion) so.proper_motion = false;
  if (o.no_aberration) so.aberration = false;
  so.Check();
  if (!o.random && (std::isnan(o.ra_deg) || std::isnan(o.dec_deg))) {
    throw InputError("simulate frame: give --ra-deg and --dec-deg (and --roll-deg), or --random --seed N");
  }
  if (!o.random && (std::abs(o.dec_deg) > 90 || !std::isfinite(o.ra_deg) || !std::isfinite(o.roll_deg))) {
    throw InputError("simulate frame: --dec-deg must be in [-90, 90] and angles finite");
  }
  if (o.count < 1 || o.count > 100000) throw InputError("simulate frame: --count must be 1..100000");
  SceneSimOptions scene = o.scene;
  if (!o.false_objects.empty()) {
    if (o.false_objects.size() > 2) throw InputError("--false-objects", "give N or MIN,MAX");
    scene.false_objects_min = o.false_objects.front();
    scene.false_objects_max = o.false_objects.back();
  }
  scene.Check();
  const StarCatalog cat = LoadXplanetBsc(o.catalog);
  std::error_code ec;
  std::filesystem::create_directories(o.out, ec);
  if (!std::filesystem::is_directory(o.out)) throw InputError(o.out, "cannot create output directory");
  WriteJsonFile(o.out + "/camera.json", CameraToJson(cam));
  for (int k = 0; k < o.count; ++k) {
    const uint64_t seed = o.seed + static_cast<uint64_t>(k);
    const Quat q = o.random ? RandomAttitude(seed)
                            : QuatFromRaDecRoll(o.ra_deg * kDegToRad, o.dec_deg * kDegToRad, o.roll_deg * kDegToRad);
    char name[64];
    std::snprintf(name, sizeof(name), "frame_%04d", k);
    const std::string base = o.out + "/" + name;
    if (o.scene_csv || o.centroids_only) {
      // Its own random stream (seed offset), so that adding the list leaves the frame unchanged.
      const SimulatedScene sc = SimulateScene(cam, cat, q, scene, seed ^ 0x5CE7E5EEDull);
      WriteSceneCsv(base + "_centroids.csv", sc);
      if (o.centroids_only) {
        const RaDecRoll a = RaDecRollFromQuat(sc.q_inertial_from_sensor);
        const auto qw = ToWxyz(sc.q_inertial_from_sensor);
        Json truth = {{"q", {qw[0], qw[1], qw[2], qw[3]}},
                      {"ra_deg", a.ra_rad * kRadToDeg},
                      {"dec_deg", a.dec_rad * kRadToDeg},
                      {"roll_deg", a.roll_rad * kRadToDeg},
                      {"seed", seed},
                      {"true_stars", sc.true_stars},
                      {"false_objects", sc.false_objects},
                      {"centroids", std::string(name) + "_centroids.csv"},
                      {"catalog", cat.source}};
        WriteJsonFile(base + ".json", truth);
        std::cout << base << "_centroids.csv: " << sc.true_stars << " stars, " << sc.false_objects
                  << " false objects\n";
        continue;
      }
    }
    const SimulatedFrame f = SimulateFrame(cam, cat, q, so, seed);
    WritePng16(base + ".png", f.image);
    Json truth = TruthToJson(f, cam, so);
    truth["file"] = std::string(name) + ".png";
    truth["catalog"] = cat.source;
    WriteJsonFile(base + ".json", truth);
    std::cout << base << ".png: " << f.stars.size() << " stars, " << f.artefacts.size() << " artefacts, ra "
              << truth["ra_deg"].get<double>() << " dec " << truth["dec_deg"].get<double>() << " roll "
              << truth["roll_deg"].get<double>() << " deg\n";
  }
}

}  // namespace
}  // namespace ssiu::cli

SSIU_REGISTER_COMMAND(simulate_frame, [](CLI::App& root) {
  using namespace ssiu::cli;
  CLI::App* sim = GetOrAddSubcommand(root, "simulate", "Simulate data (star frames, gyro logs)");
  CLI::App* cmd = sim->add_subcommand("frame", "Simulate CCD star frames with truth JSON (16-bit PNG)");
  auto o = std::make_shared<Opts>();
  cmd->add_option("--camera", o->camera, "camera.json (default: 1024x1024, 16.6 deg FOV)");
  cmd->add_option("--ra-deg", o->ra_deg, "Boresight right ascension");
  cmd->add_option("--dec-deg", o->dec_deg, "Boresight declination");
  cmd->add_option("--roll-deg", o->roll_deg, "Roll about the boresight (conventions.md)");
  cmd->add_flag("--random", o->random, "Random attitude (uniform over rotations) from the seed");
  cmd->add_option("--seed", o->seed, "Random seed (frame k uses seed + k)");
  cmd->add_option("--count", o->count, "Number of frames");
  cmd->add_option("--out", o->out, "Output directory")->required();
  cmd->add_option("--config", o->config, "JSON file of simulator options (keys as the flags, with _)");
  cmd->add_option("--catalog", o->catalog, "Star catalog (xplanet BSC format)");
  cmd->add_flag("--no-shot-noise", o->no_shot_noise, "Switch photon shot noise off");
  cmd->add_flag("--scene-csv", o->scene_csv,
                "Also write frame_NNNN_centroids.csv: a centroid list of the same attitude (x_px,y_px,flux,"
                "sigma_px,star_id,mag; star_id -1 = false object) for `ssiu solve --centroids`");
  cmd->add_flag("--centroids-only", o->centroids_only, "Write only the centroid lists and truth JSON (no PNG)");
  cmd->add_option("--false-objects", o->false_objects,
                  "Centroid lists: N or MIN,MAX false objects (uniform count), as bright as the stars in distribution")
      ->delimiter(',');
  cmd->add_option("--missing-fraction", o->scene.missing_fraction, "Centroid lists: chance that a star is missing")
      ->capture_default_str();
  cmd->add_option("--centroid-noise-px", o->scene.centroid_noise_px, "Centroid lists: 1-sigma noise per axis")
      ->capture_default_str();
  cmd->add_option("--scene-mag-max", o->scene.mag_max, "Centroid lists: faintest star seen")->capture_default_str();
  cmd->add_option("--flux-noise-mag", o->scene.flux_noise_mag,
                  "Centroid lists: 1-sigma scatter (mag) of every flux about 10^(-0.4 V) (photometric noise)")
      ->capture_default_str();
  cmd->add_option(
      "--time", o->time,
      "Frame UTC time, ISO 8601: stars drawn with proper motion to that date and aberration (docs/simulator.md)");
  cmd->add_flag("--no-proper-motion", o->no_proper_motion, "With --time: no proper motion");
  cmd->add_flag("--no-aberration", o->no_aberration, "With --time: no stellar aberration");
  auto flags = std::make_shared<std::vector<std::pair<std::string, CLI::Option*>>>();
  for (const std::string& name : ssiu::FrameSimOptionNames()) {
    std::string flag = "--" + name;
    std::replace(flag.begin(), flag.end(), '_', '-');
    flags->emplace_back(name, cmd->add_option(flag)->description("Simulator option " + name + " (docs/simulator.md)"));
  }
  cmd->callback([o, flags] { Run(*o, *flags); });
});
