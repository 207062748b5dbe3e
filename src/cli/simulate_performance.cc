// `ssiu simulate performance`: a slow slew across the field with the ECSS error contributions injected
// (groundtest/performance.h SimulatePerformance), as the files `ssiu performance` reads.
#include <filesystem>
#include <memory>
#include <sstream>

#include "cli/command.h"
#include "core/csv.h"
#include "core/error.h"
#include "core/json.h"
#include "groundtest/performance.h"
#include "groundtest/solve_pictures.h"

namespace ssiu::cli {
namespace {

struct Opts {
  PerformanceSimulation sim;
  std::string out, camera, bias_arcsec, drift_arcsec_per_c;
  double star_speed_px_s = 4.0;
};

Vec3 ParseVec3(const std::string& s, const std::string& flag) {
  Vec3 v = Vec3::Zero();
  if (s.empty()) return v;
  std::istringstream in(s);
  char c1 = 0, c2 = 0;
  if (!(in >> v.x() >> c1 >> v.y() >> c2 >> v.z()) || c1 != ',' || c2 != ',' || !v.allFinite())
    throw InputError(flag, "expected X,Y,ROLL");
  return v;
}

SSIU_REGISTER_COMMAND(simulate_performance, [](CLI::App& root) {
  auto* sim = GetOrAddSubcommand(root, "simulate", "Simulate data");
  auto* cmd = sim->add_subcommand(
      "performance",
      "A slow diagonal slew of one head with ECSS error contributions injected: DIR/measured.csv, reference.csv, "
      "temperature.csv, camera.json, truth.json (the 1-sigma of each contribution alone) for `ssiu performance`");
  auto o = std::make_shared<Opts>();
  o->sim.camera = MakeCamera(512, 512, 16.6);
  o->sim.temp_amplitude_c = 4;
  cmd->add_option("--out", o->out, "Output directory")->required();
  cmd->add_option("--camera", o->camera, "camera.json (default 512 x 512 px, 16.6 deg; its distortion is not used)");
  cmd->add_option("--duration-s", o->sim.duration_s, "Length of the test")->capture_default_str();
  cmd->add_option("--rate-hz", o->sim.rate_hz, "Sample rate")->capture_default_str();
  cmd->add_option("--star-speed-px-s", o->star_speed_px_s, "Star image speed on the detector (diagonal)")
      ->capture_default_str();
  cmd->add_option("--stars-per-deg2", o->sim.stars_per_deg2, "Random star density")->capture_default_str();
  cmd->add_option("--seed", o->sim.seed, "Random seed")->capture_default_str();
  cmd->add_option("--bias-arcsec", o->bias_arcsec, "Fixed bias X,Y,ROLL");
  cmd->add_option("--distortion-k1", o->sim.distortion_k1, "Brown k1 the solver does not know")->capture_default_str();
  cmd->add_option("--intra-pixel-px", o->sim.intra_pixel_px, "Amplitude of the sin(2 pi x), sin(2 pi y) pattern")
      ->capture_default_str();
  cmd->add_option("--noise-px", o->sim.noise_px, "White centroid noise, 1 sigma per axis")->capture_default_str();
  cmd->add_option("--drift-arcsec-per-c", o->drift_arcsec_per_c, "Mount drift X,Y,ROLL per degree C");
  cmd->add_option("--temp-amplitude-c", o->sim.temp_amplitude_c, "temp_c = 20 + amplitude sin(2 pi t / period)")
      ->capture_default_str();
  cmd->add_option("--temp-period-s", o->sim.temp_period_s, "Temperature period (0 = the test's length)")
      ->capture_default_str();
  cmd->callback([o] {
    PerformanceSimulation s = o->sim;
    if (!o->camera.empty()) s.camera = LoadCamera(o->camera);
    if (!(s.duration_s > 0) || !(s.rate_hz > 0) || !(o->star_speed_px_s > 0) || !(s.stars_per_deg2 > 0))
      throw InputError("ssiu simulate performance",
                       "--duration-s, --rate-hz, --star-speed-px-s, --stars-per-deg2 must be > 0");
    if (s.duration_s * s.rate_hz > 1e6) throw InputError("--duration-s", "more than 1e6 samples");
    if (s.temp_period_s <= 0) s.temp_period_s = s.duration_s;
    const double v = o->star_speed_px_s / std::sqrt(2.0);
    s.rate_rad_s = Vec3(v / s.camera.FocalYPx(), -v / s.camera.FocalXPx(), 0);
    s.bias_rad = ParseVec3(o->bias_arcsec, "--bias-arcsec") * kArcsecToRad;
    s.drift_rad_per_c = ParseVec3(o->drift_arcsec_per_c, "--drift-arcsec-per-c") * kArcsecToRad;
    std::error_code ec;
    std::filesystem::create_directories(o->out, ec);
    if (!std::filesystem::is_directory(o->out, ec)) throw InputError(o->out, "cannot create output directory");
    const SimulatedPerformance r = SimulatePerformance(s);
    WriteAttitudeCsv(o->out + "/measured.csv", r.measured);  // sigma columns 0: not stated
    WriteAttitudeCsv(o->out + "/reference.csv", r.reference);
    WriteCsv(o->out + "/temperature.csv", {"t_s", "temp_c"}, {r.temperature.t_s, r.temperature.temp_c}, 12);
    Camera written = s.camera;
    written.distortion = Distortion{};  // what the solver assumed
    WriteJsonFile(o->out + "/camera.json", CameraToJson(written));
    auto arcsec = [](const Vec3& x) {
      return Json::array({x.x() * kRadToArcsec, x.y() * kRadToArcsec, x.z() * kRadToArcsec});
    };
    Json truth;
    truth["bias_arcsec"] = arcsec(r.bias_rad);
    truth["fov_spatial_arcsec"] = arcsec(r.fov_rad);
    truth["pixel_spatial_arcsec"] = arcsec(r.pixel_rad);
    truth["temporal_noise_arcsec"] = arcsec(r.noise_rad);
    truth["thermoelastic_arcsec"] = arcsec(r.thermal_rad);
    WriteJsonFile(o->out + "/truth.json", truth);
  });
});

}  // namespace
}  // namespace ssiu::cli
