// `ssiu groundtest simulate`: the virtual test stand (groundtest/virtual_stand.h): tracker frames of
// the mask through the collimator, aux-camera photos of the fiducials, noisy encoder angles, truth;
// with --solve also the tracker's attitudes (detect -> identify -> QUEST) as computed.csv; --slew makes
// the pictures a slow slew across the field (the sequence of `ssiu performance`).
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>

#include "cli/command.h"
#include "core/csv.h"
#include "core/error.h"
#include "groundtest/solve_pictures.h"
#include "groundtest/virtual_stand.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string mask, camera, out, catalog, tag_family;
  StandSimOptions sim;
  std::vector<double> mis = {3.0, -2.0, 4.0};
  uint64_t seed = 1;
  bool solve = false, hide_tags = false;
};

std::string Indexed(const std::string& dir, const char* stem, size_t i) {
  char b[64];
  std::snprintf(b, sizeof b, "/%s_%03zu.png", stem, i);
  return dir + b;
}

SSIU_REGISTER_COMMAND(groundtest_simulate, [](CLI::App& root) {
  auto* gt = GetOrAddSubcommand(root, "groundtest", "Star-tracker ground test: mask, reference, compare, simulate");
  auto* cmd = gt->add_subcommand("simulate", "Virtual test stand: tracker frames, fiducial photos, encoders, truth");
  auto o = std::make_shared<Opts>();
  cmd->add_option("--mask", o->mask, "mask.json")->required();
  cmd->add_option("--camera", o->camera, "Tracker camera.json: checked against the mask's");
  cmd->add_option("--out", o->out, "Output directory")->required();
  cmd->add_option("--positions", o->sim.positions, "Stand positions (pictures)")->capture_default_str();
  cmd->add_option("--step-s", o->sim.step_s, "Time between pictures")->capture_default_str();
  cmd->add_option("--max-angle-deg", o->sim.max_angle_deg, "Stand az/el spread")->capture_default_str();
  cmd->add_flag("--slew", o->sim.slew,
                "A slow slew: az from -max to +max (el half that) in even steps, no roll (for ssiu performance)");
  cmd->add_option("--misalignment-arcmin", o->mis, "Hidden stand-to-tracker misalignment x,y,z (sensor axes)")
      ->expected(3)
      ->delimiter(',');
  cmd->add_option("--encoder-sigma-arcsec", o->sim.encoder_sigma_arcsec, "Encoder noise per axis")
      ->capture_default_str();
  cmd->add_option("--plate-shift-mm", o->sim.plate_shift_mm, "Plate displacement in its holder")->capture_default_str();
  cmd->add_option("--plate-turn-deg", o->sim.plate_turn_deg, "Plate in-plane turn")->capture_default_str();
  cmd->add_option("--defocus-px", o->sim.view.detector.defocus_radius_px, "Defocus disk radius")->capture_default_str();
  cmd->add_option("--psf-sigma-px", o->sim.view.detector.psf_sigma_px, "Gaussian PSF sigma")->capture_default_str();
  cmd->add_option("--background-e-per-s", o->sim.view.detector.background_e_per_s, "Uniform background")
      ->capture_default_str();
  cmd->add_option("--stray-gradient", o->sim.view.stray_gradient, "Stray-light gradient across the frame")
      ->capture_default_str();
  cmd->add_option("--stray-glow-e-per-s", o->sim.view.stray_glow_e_per_s, "Stray-light glow peak")
      ->capture_default_str();
  cmd->add_option("--photo-noise-dn", o->sim.photo.noise_dn, "Aux photo pixel noise")->capture_default_str();
  cmd->add_option("--photo-tag-family", o->tag_family, "Draw another tag family on the photos (tests)");
  cmd->add_flag("--photo-hide-tags", o->hide_tags, "Draw the photos without fiducials (tests)");
  cmd->add_option("--seed", o->seed, "Random seed")->capture_default_str();
  cmd->add_flag("--solve", o->solve, "Also solve the tracker frames -> computed.csv");
  cmd->add_option("--catalog", o->catalog, "Solver catalog directory for --solve (default: cache)");
  cmd->callback([o] {
    const Mask m = LoadMask(o->mask);
    if (!o->camera.empty()) CheckMaskCamera(m, LoadCamera(o->camera), o->mask);
    StandSimOptions so = o->sim;
    so.misalignment_arcmin = Vec3(o->mis[0], o->mis[1], o->mis[2]);
    so.photo.tag_family = o->tag_family;
    so.photo.hide_tags = o->hide_tags;
    const StandSimulation s = SimulateStand(m, so, o->seed);
    std::error_code ec;
    std::filesystem::create_directories(o->out, ec);
    if (ec) throw InputError(o->out, "cannot create the output directory");
    std::vector<std::vector<double>> enc(4);
    for (size_t i = 0; i < s.pictures.size(); ++i) {
      const StandPicture& p = s.pictures[i];
      WritePng16(Indexed(o->out, "frame", i), p.frame);
      WritePng8(Indexed(o->out, "photo", i), so.aux.camera.width, so.aux.camera.height, p.photo);
      enc[0].push_back(p.t_s), enc[1].push_back(p.enc_az_deg), enc[2].push_back(p.enc_el_deg),
          enc[3].push_back(p.enc_rot_deg);
    }
    WriteCsv(o->out + "/encoders.csv", {"t_s", "az_deg", "el_deg", "rot_deg"}, enc);
    WriteJsonFile(o->out + "/aux_camera.json", AuxCameraToJson(so.aux));
    Json cam = CameraToJson(m.camera);
    WriteJsonFile(o->out + "/camera.json", cam);
    WriteJsonFile(o->out + "/truth.json", s.TruthJson(m));
    // What an ideal tracker reports at each picture, as conventions.md's attitude CSV (a reference for
    // `ssiu performance` or `groundtest compare`).
    std::vector<AttitudeSample> truth;
    for (const auto& p : s.pictures) {
      AttitudeSample t;
      t.t_s = p.t_s;
      t.q = p.q_true;
      truth.push_back(t);
    }
    WriteAttitudeCsv(o->out + "/truth.csv", truth);
    int solved = 0;
    if (o->solve) {
      const StarIdentifier id = MakeIdentifierForCamera(o->catalog, m.camera, 0.0);
      std::vector<AttitudeSample> comp;
      for (const auto& p : s.pictures) {
        const PictureSolve ps = SolveStandPicture(id, p.frame.view(), m.camera, so.view.detector.gain_e_per_adu, p.t_s);
        if (ps.status == SolveStatus::kSolved) comp.push_back(ps.sample), ++solved;
      }
      WriteAttitudeCsv(o->out + "/computed.csv", comp);
    }
    std::cerr << s.pictures.size() << " pictures -> " << o->out;
    if (o->solve) std::cerr << " (" << solved << " solved -> computed.csv)";
    std::cerr << "\n";
  });
});

}  // namespace
}  // namespace ssiu::cli
