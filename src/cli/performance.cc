// `ssiu performance`: the ECSS-E-ST-60-20C split of one head's attitude error (groundtest/performance.h).
#include "groundtest/performance.h"

#include <cstdio>
#include <memory>

#include "cli/command.h"
#include "core/camera.h"
#include "core/error.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string measured, reference, camera, temperature, json = "-", plots;
  PerformanceOptions options;
};

SSIU_REGISTER_COMMAND(performance, [](CLI::App& root) {
  auto* cmd = root.add_subcommand(
      "performance",
      "ECSS-E-ST-60-20C split of one head's attitude error: bias, temporal noise, FOV and pixel spatial, "
      "thermo-elastic");
  auto o = std::make_shared<Opts>();
  cmd->add_option("--measured", o->measured, "The head's attitudes: CSV t_s,qw,qx,qy,qz or a CCSDS AEM/ACM")
      ->required();
  cmd->add_option("--reference", o->reference,
                  "Reference attitudes of the same head (a slow slew across the field): CSV or AEM/ACM")
      ->required();
  cmd->add_option("--camera", o->camera, "camera.json of the head (pixel scale and field)")->required();
  cmd->add_option("--temperature", o->temperature, "CSV t_s,temp_c: the thermo-elastic part follows it");
  cmd->add_option("--json", o->json, "Output JSON, - for stdout")->capture_default_str();
  cmd->add_option("--plots", o->plots,
                  "Directory for error_parts_{x,y,roll}.png, spectrum.png, error_vs_temperature.png");
  cmd->add_option("--fov-band-crossings", o->options.fov_band_crossings,
                  "FOV band up to this many field-crossing frequencies; pixel bands as wide")
      ->capture_default_str();
  cmd->add_option("--pixel-harmonics", o->options.pixel_harmonics, "Pixel bands at 1..N x the pixel-crossing frequency")
      ->capture_default_str();
  cmd->add_option("--time-tolerance-s", o->options.time_tolerance_s, "Pairing tolerance of measured and reference")
      ->capture_default_str();
  cmd->callback([o] {
    const Camera cam = LoadCamera(o->camera);
    std::string epoch_utc;  // CCSDS messages: both on the reference's time axis
    const std::vector<AttitudeSample> reference = ReadAttitudeSeries(o->reference, &epoch_utc);
    const std::vector<AttitudeSample> measured = ReadAttitudeSeries(o->measured, &epoch_utc);
    const TemperatureLog temperature = o->temperature.empty() ? TemperatureLog{} : ReadTemperatureLog(o->temperature);
    const PerformanceReport r = AnalysePerformance(measured, reference, cam, temperature, o->options);
    WriteJsonFile(o->json, PerformanceReportToJson(r));
    if (!o->plots.empty()) WritePerformancePlots(r, o->plots);
    auto line = [](const char* name, const Vec3& v) {
      std::fprintf(stderr, "  %-16s %9.3f %9.3f %9.3f\n", name, v.x() * kRadToArcsec, v.y() * kRadToArcsec,
                   v.z() * kRadToArcsec);
    };
    std::fprintf(stderr, "performance: %d samples at %.3g Hz; field crossing %.3g Hz, pixel crossing %.3g, %.3g Hz\n",
                 r.samples, r.sample_rate_hz, r.field_crossing_hz, r.pixel_crossing_hz.x(), r.pixel_crossing_hz.y());
    std::fprintf(stderr, "  %-16s %9s %9s %9s (arcsec)\n", "", "x", "y", "roll");
    line("bias", r.bias_rad);
    line("temporal noise", r.temporal_noise_rad);
    line("FOV spatial", r.fov_spatial_rad);
    line("pixel spatial", r.pixel_spatial_rad);
    line("thermo-elastic", r.thermoelastic_rad);
    for (const std::string& w : r.warnings) std::fprintf(stderr, "  warning: %s\n", w.c_str());
  });
});

}  // namespace
}  // namespace ssiu::cli
