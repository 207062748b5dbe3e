// `ssiu detect`: star centroids, background/noise and rejected interferers of one frame, as JSON.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>

#include "cli/command.h"
#include "cli/smear_flags.h"
#include "core/camera.h"
#include "core/error.h"
#include "detect/detect.h"
#include "detect/detect_json.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::string frame, camera, defects, dark, json;
  double threshold_sigma = DetectOptions{}.threshold_sigma;
  double psf_sigma_px = 0;
  double gain_e_per_adu = 0;
  int max_stars = DetectOptions{}.max_stars;
  SmearFlags smear;
};

void Run(const Opts& o) {
  const Frame fr = o.dark.empty() ? ReadFrame(o.frame) : SubtractDark(ReadFrame(o.frame), ReadFrame(o.dark));
  // Detect() needs 16x16 pixels for its background tiles (the smallest camera.json allows).
  if (fr.image.width < 16 || fr.image.height < 16) {
    throw InputError(o.frame, "image is " + std::to_string(fr.image.width) + "x" + std::to_string(fr.image.height) +
                                  ": too small for star detection (at least 16x16)");
  }
  if (!std::isfinite(o.gain_e_per_adu) || o.gain_e_per_adu < 0) {
    throw InputError("--gain-e-per-adu", "must be a finite number >= 0");
  }
  DetectOptions opt;
  opt.threshold_sigma = o.threshold_sigma;
  opt.psf_sigma_px = o.psf_sigma_px;
  opt.saturation_adu = fr.saturation_adu;
  if (o.max_stars < 0) throw InputError("--max-stars", "must be >= 0 (0: no cap)");
  // No cap: a frame cannot hold more sources than a quarter of its pixels (each is a local maximum).
  const long long no_cap = static_cast<long long>(fr.image.width) * fr.image.height / 4 + 1;
  opt.max_stars = o.max_stars > 0 ? o.max_stars : static_cast<int>(std::min<long long>(no_cap, 100000000));
  Camera cam;
  if (!o.camera.empty()) {
    cam = LoadCamera(o.camera);
    if (cam.width != fr.image.width || cam.height != fr.image.height) {
      throw InputError(o.frame, "image is " + std::to_string(fr.image.width) + "x" + std::to_string(fr.image.height) +
                                    " but " + o.camera + " says " + std::to_string(cam.width) + "x" +
                                    std::to_string(cam.height));
    }
    opt.gain_e_per_adu = cam.gain_e_per_adu;
  }
  if (o.gain_e_per_adu > 0) opt.gain_e_per_adu = o.gain_e_per_adu;
  opt.smear = SmearFromFlags(o.smear, o.camera.empty() ? nullptr : &cam);
  try {
    opt.Check();
  } catch (const std::invalid_argument& e) {
    throw InputError(e.what());
  }
  DefectMap map;
  if (!o.defects.empty()) {
    map = LoadDefectMap(o.defects);
    if (!map.empty() && (map.width != fr.image.width || map.height != fr.image.height)) {
      throw InputError(o.defects, "defect map is " + std::to_string(map.width) + "x" + std::to_string(map.height) +
                                      ", frame is " + std::to_string(fr.image.width) + "x" +
                                      std::to_string(fr.image.height));
    }
  }
  const Detections d = Detect(fr.image.view(), opt, map.empty() ? nullptr : &map);
  Json j = DetectionsToJson(d, o.frame, fr.value_scale, fr.value_offset);
  j["grey_conversion"] = fr.grey_conversion;
  j["bit_depth"] = fr.bit_depth;
  if (opt.smear.active()) {
    const Vec3 w_dps = opt.smear.rate_rad_s * kRadToDeg;
    j["smear_model"] = {{"rate_dps", {w_dps.x(), w_dps.y(), w_dps.z()}}, {"exposure_s", opt.smear.exposure_s}};
  }
  if (!o.json.empty()) WriteJsonFile(o.json, j);
  if (o.json != "-") {
    std::cerr << o.frame << ": " << d.stars.size() << " stars, " << d.rejected.size() << " rejected, background "
              << j["background_adu"].get<double>() << " ADU, noise " << j["noise_adu"].get<double>() << " ADU, "
              << d.timing_ms.at("total") << " ms\n";
  }
}

}  // namespace
}  // namespace ssiu::cli

SSIU_REGISTER_COMMAND(detect, [](CLI::App& root) {
  using namespace ssiu::cli;
  CLI::App* cmd = root.add_subcommand("detect", "Detect stars in a frame (PNG/TIFF 8/16-bit, FITS)");
  auto o = std::make_shared<Opts>();
  cmd->add_option("frame", o->frame, "Image file")->required();
  cmd->add_option("--camera", o->camera, "camera.json (checks the size; gain_e_per_adu if present)");
  cmd->add_option("--defects", o->defects, "Static defect map PNG (from `ssiu defects build`)");
  cmd->add_option("--dark", o->dark, "Dark or median frame to subtract first (same camera and size)");
  cmd->add_option("--json", o->json, "Output JSON file, - for stdout");
  cmd->add_option("--threshold-sigma", o->threshold_sigma, "Detection threshold (matched-filter sigmas)");
  cmd->add_option("--psf-sigma-px", o->psf_sigma_px, "Expected PSF sigma (0 = estimate)");
  cmd->add_option("--gain-e-per-adu", o->gain_e_per_adu, "Detector gain for shot-noise weights");
  cmd->add_option("--max-stars", o->max_stars,
                  "Report at most this many stars, brightest first (0: no cap, a deep search)");
  AddSmearFlags(cmd, &o->smear);
  cmd->callback([o] { Run(*o); });
});
