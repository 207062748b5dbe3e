// `ssiu detect`: star centroids, background/noise and rejected interferers of one frame, as JSON; many
// frames (or a batch flag) are a batch, one JSON line per frame (cli/batch.h).
#include "detect/detect.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>

#include "attitude/star_solver.h"
#include "cli/batch.h"
#include "cli/command.h"
#include "cli/smear_flags.h"
#include "core/camera.h"
#include "core/error.h"
#include "detect/detect_json.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::vector<std::string> frames;
  std::string camera, defects, dark, json;
  double threshold_sigma = DetectOptions{}.threshold_sigma;
  double psf_sigma_px = 0;
  double gain_e_per_adu = 0;
  int max_stars = DetectOptions{}.max_stars;
  SmearFlags smear;
  BatchFlags batch;
};

// What every frame of a run shares: the checked flags, the camera, the defect map, the dark.
struct Setup {
  DetectOptions opt;
  Camera cam;
  DefectMap map;
  Frame dark;
};

std::string Size(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

Setup Prepare(const Opts& o) {
  Setup s;
  if (!std::isfinite(o.gain_e_per_adu) || o.gain_e_per_adu < 0) {
    throw InputError("--gain-e-per-adu", "must be a finite number >= 0");
  }
  s.opt.threshold_sigma = o.threshold_sigma;
  s.opt.psf_sigma_px = o.psf_sigma_px;
  if (o.max_stars < 0) throw InputError("--max-stars", "must be >= 0 (0: no cap)");
  if (!o.defects.empty()) s.map = LoadDefectMap(o.defects);
  if (!o.camera.empty()) {
    const Json j = ReadJsonFile(o.camera);
    s.cam = CameraFromJson(j, o.camera);
    s.opt.gain_e_per_adu = s.cam.gain_e_per_adu;
    // camera.json's known hot pixels join the defect map (repaired, not detected).
    const CameraExtras e = CameraExtrasFromJson(j, s.cam, o.camera);
    if (!e.hot_pixels.empty() && !s.map.empty() && (s.map.width != s.cam.width || s.map.height != s.cam.height)) {
      throw InputError(o.defects, "defect map is " + Size(s.map.width, s.map.height) + " but " + o.camera + " says " +
                                      Size(s.cam.width, s.cam.height));
    }
    MarkHotPixels(e.hot_pixels, s.cam.width, s.cam.height, &s.map);
    UseCameraExtras(e, &s.opt);  // its psf_sigma_px where --psf-sigma-px is not given
  }
  if (o.gain_e_per_adu > 0) s.opt.gain_e_per_adu = o.gain_e_per_adu;
  s.opt.smear = SmearFromFlags(o.smear, o.camera.empty() ? nullptr : &s.cam);
  if (!o.dark.empty()) s.dark = ReadFrame(o.dark);
  return s;
}

// One frame -> its JSON (the single-frame output of `ssiu detect`); *d keeps the detections.
Json DetectOne(const Opts& o, const Setup& s, const std::string& path, Detections* d) {
  const Frame fr = o.dark.empty() ? ReadFrame(path) : SubtractDark(ReadFrame(path), s.dark);
  // Detect() needs 16x16 pixels for its background tiles (the smallest camera.json allows).
  if (fr.image.width < 16 || fr.image.height < 16) {
    throw InputError(
        path, "image is " + Size(fr.image.width, fr.image.height) + ": too small for star detection (at least 16x16)");
  }
  if (!o.camera.empty() && (s.cam.width != fr.image.width || s.cam.height != fr.image.height)) {
    throw InputError(path, "image is " + Size(fr.image.width, fr.image.height) + " but " + o.camera + " says " +
                               Size(s.cam.width, s.cam.height));
  }
  if (!s.map.empty() && (s.map.width != fr.image.width || s.map.height != fr.image.height)) {
    throw InputError(o.defects, "defect map is " + Size(s.map.width, s.map.height) + ", frame is " +
                                    Size(fr.image.width, fr.image.height));
  }
  DetectOptions opt = s.opt;
  opt.saturation_adu = fr.saturation_adu;
  // No cap: a frame cannot hold more sources than a quarter of its pixels (each is a local maximum).
  const long long no_cap = static_cast<long long>(fr.image.width) * fr.image.height / 4 + 1;
  opt.max_stars = o.max_stars > 0 ? o.max_stars : static_cast<int>(std::min<long long>(no_cap, 100000000));
  opt.Check();
  *d = Detect(fr.image.view(), opt, s.map.empty() ? nullptr : &s.map);
  Json j = DetectionsToJson(*d, path, fr.value_scale, fr.value_offset);
  j["grey_conversion"] = fr.grey_conversion;
  j["bit_depth"] = fr.bit_depth;
  if (opt.smear.active()) {
    const Vec3 w_dps = opt.smear.rate_rad_s * kRadToDeg;
    j["smear_model"] = {{"rate_dps", {w_dps.x(), w_dps.y(), w_dps.z()}}, {"exposure_s", opt.smear.exposure_s}};
  }
  return j;
}

void Run(const Opts& o) {
  const Setup s = Prepare(o);
  Detections d;
  const Json j = DetectOne(o, s, o.frames[0], &d);
  if (!o.json.empty()) WriteJsonFile(o.json, j);
  if (o.json != "-") {
    std::cerr << o.frames[0] << ": " << d.stars.size() << " stars, " << d.rejected.size() << " rejected, background "
              << j["background_adu"].get<double>() << " ADU, noise " << j["noise_adu"].get<double>() << " ADU, "
              << d.timing_ms.at("total") << " ms\n";
  }
}

// --csv columns of a batch (docs/detection.md "Batch").
const std::vector<std::string> kBatchColumns = {"file",         "status",       "width",          "height",
                                                "num_stars",    "num_rejected", "background_adu", "noise_adu",
                                                "psf_sigma_px", "time_ms",      "message"};

void RunBatchDetect(const Opts& o, const std::vector<std::string>& inputs) {
  if (!o.json.empty()) throw InputError("--json", "is one frame's output: a batch writes --jsonl and/or --csv");
  const Setup s = Prepare(o);
  RunBatch("ssiu detect", inputs, o.batch, kBatchColumns, [&](const std::string& input) {
    Detections d;
    Json j = DetectOne(o, s, input, &d);
    j["status"] = "ok";
    std::vector<std::string> row = {CsvText(input),
                                    "ok",
                                    CsvNumber(j["width"]),
                                    CsvNumber(j["height"]),
                                    CsvNumber(d.stars.size()),
                                    CsvNumber(d.rejected.size()),
                                    CsvNumber(j["background_adu"]),
                                    CsvNumber(j["noise_adu"]),
                                    CsvNumber(j["psf_sigma_px"]),
                                    CsvNumber(d.timing_ms.at("total")),
                                    ""};
    return BatchRecord{std::move(j), std::move(row)};
  });
}

}  // namespace
}  // namespace ssiu::cli

SSIU_REGISTER_COMMAND(detect, [](CLI::App& root) {
  using namespace ssiu::cli;
  CLI::App* cmd = root.add_subcommand("detect", "Detect stars in a frame (PNG/TIFF 8/16-bit, FITS)");
  auto o = std::make_shared<Opts>();
  cmd->add_option("frames", o->frames, "Image file; more than one is a batch");
  cmd->add_option("--camera", o->camera, "camera.json (checks the size; gain_e_per_adu if present)");
  cmd->add_option("--defects", o->defects, "Static defect map PNG (from `ssiu defects build`)");
  cmd->add_option("--dark", o->dark, "Dark or median frame to subtract first (same camera and size)");
  cmd->add_option("--json", o->json, "Output JSON file, - for stdout");
  cmd->add_option("--threshold-sigma", o->threshold_sigma, "Detection threshold (matched-filter sigmas)");
  cmd->add_option("--psf-sigma-px", o->psf_sigma_px,
                  "Expected PSF sigma (0 = camera.json's psf_sigma_px when given, else estimated from the frame)");
  cmd->add_option("--gain-e-per-adu", o->gain_e_per_adu, "Detector gain for shot-noise weights");
  cmd->add_option("--max-stars", o->max_stars,
                  "Report at most this many stars, brightest first (0: no cap, a deep search)");
  AddSmearFlags(cmd, &o->smear);
  AddBatchFlags(cmd, &o->batch, "the --json of that frame with \"status\": \"ok\"");
  cmd->footer(
      "Batch: `ssiu detect F1.png F2.fits ... --jsonl OUT.jsonl [--csv OUT.csv] [--threads N]` (or --list FILE);\n"
      "  exit status 1 when any frame failed (its record has status \"error\"), after every frame was\n"
      "  processed. --csv columns: " +
      CsvJoin(kBatchColumns) + "\n  (time_ms: detection without reading the file; empty cells when failed).");
  cmd->callback([o] {
    const std::vector<std::string> inputs = BatchInputs(o->frames, o->batch);
    if (inputs.empty()) throw ssiu::InputError("ssiu detect", "give a FRAME (or several, or --list FILE)");
    if (inputs.size() == 1 && !o->batch.given()) {
      Run(*o);
    } else {
      RunBatchDetect(*o, inputs);
    }
  });
});
