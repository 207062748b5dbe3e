// `ssiu discover gyro LOG.csv [LOG2.csv ...] --json OUT` and `ssiu discover frames FRAME... --camera
// CAM.json --json OUT`: model discrepancy analysis (docs/discrepancy.md). The library does the work
// (analysis/discover_gyro.h, analysis/discover_frames.h); this file parses flags and writes JSON.
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "analysis/discover_frames.h"
#include "analysis/discover_gyro.h"
#include "attitude/star_solver.h"
#include "core/camera.h"
#include "core/error.h"
#include "core/image.h"
#include "cli/command.h"
#include "core/json.h"

namespace {

struct GyroOpts {
  std::vector<std::string> logs;
  std::string json;
  ssiu::GyroDiscoverOptions opt;
};

struct FrameOpts {
  std::vector<std::string> frames;
  std::string camera, json, plot, dark, catalog;
  double fov_tolerance_pct = 1.0;
  ssiu::FrameDiscoverOptions opt;
};

}  // namespace

SSIU_REGISTER_COMMAND(discover_frames, [](CLI::App& root) {
  auto* discover = ssiu::cli::GetOrAddSubcommand(root, "discover", "Find what the model gets wrong in measured data");
  auto* cmd = discover->add_subcommand(
      "frames", "Solve every frame, fit star residual and flux patterns, name the camera-model cause");
  auto o = std::make_shared<FrameOpts>();
  cmd->add_option("frames", o->frames, "Frames (PNG/TIFF/FITS)")->required();
  cmd->add_option("--camera", o->camera, "camera.json (the model under test)")->required();
  cmd->add_option("--json", o->json, "Output JSON, - for stdout");
  cmd->add_option("--plot", o->plot, "Directory for residual quiver plots before/after");
  cmd->add_option("--dark", o->dark, "Dark/median frame subtracted before detection");
  cmd->add_option("--catalog", o->catalog, "Solver catalog directory (default: cache)");
  cmd->add_option("--fov-tolerance-pct", o->fov_tolerance_pct, "Focal length known to +/- this percent")
      ->capture_default_str();
  cmd->add_option("--alpha", o->opt.alpha, "Family-wise false-alarm probability")->capture_default_str();
  cmd->callback([o] {
    const ssiu::Camera cam = ssiu::LoadCamera(o->camera);
    ssiu::SolveOptions so;
    so.identify.fov_tolerance_pct = o->fov_tolerance_pct;
    const ssiu::StarIdentifier id = ssiu::MakeIdentifierForCamera(o->catalog, cam, o->fov_tolerance_pct);
    std::vector<ssiu::Frame> frames;
    for (const auto& f : o->frames) {
      frames.push_back(o->dark.empty() ? ssiu::ReadFrame(f) : ssiu::SubtractDark(ssiu::ReadFrame(f), ssiu::ReadFrame(o->dark)));
    }
    std::vector<ssiu::ImageView> views;
    for (const auto& f : frames) views.push_back(f.image.view());
    so.detect.saturation_adu = frames.front().saturation_adu;
    const ssiu::SolvedFrameSet set = ssiu::SolveFrameSet(id, views, o->frames, cam, so);
    const ssiu::FrameDiscovery d = ssiu::DiscoverFrames(set, cam, o->opt);
    std::cerr << "discover frames: " << d.frames_solved << "/" << d.frames << " solved, " << d.stars << " stars; cause "
              << d.cause;
    for (const auto& [k, v] : d.parameters) std::cerr << " " << k << "=" << v << "+-" << d.sigmas.at(k);
    std::cerr << "; residual rms " << d.residual_rms_before_arcsec << " -> " << d.residual_rms_after_arcsec
              << " arcsec (gain " << d.gain << ")\n";
    ssiu::Json j = ssiu::FrameDiscoveryToJson(d);
    j["frame_status"] = ssiu::Json::object();
    for (size_t i = 0; i < set.status.size(); ++i) j["frame_status"][o->frames[i]] = set.status[i];
    if (!o->json.empty()) ssiu::WriteJsonFile(o->json, j);
    if (!o->plot.empty()) ssiu::WriteResidualQuiver(o->plot, d, cam);
  });
});

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
