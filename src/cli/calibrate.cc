// `ssiu calibrate`: star frames + a camera guess -> fitted camera.json (fx, fy, principal point,
// distortion) with covariance and held-out residuals; with --heads, each head's camera and its
// q_body_sensor relative to head 1 -> heads.json.
#include "attitude/calibrate.h"

#include <cmath>
#include <iostream>
#include <memory>

#include "cli/command.h"
#include "core/attitude.h"
#include "core/error.h"
#include "core/heads.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::vector<std::string> frames;
  std::string camera, heads, out, json, catalog, source;
  double mag_max = 0;
  CalibrateOptions cal;
};

// What camera.json gives beyond the geometry, used as `ssiu solve` uses it (the known hot pixels repaired
// before detection, the PSF expected, the vignetting out of the fluxes); it goes into the calibrated
// camera unchanged.
struct Known {
  DefectMap hot;
  CalibrateOptions cal;
};
Known KnownOf(const CameraExtras& e, const Camera& cam, const CalibrateOptions& cal) {
  Known k;
  MarkHotPixels(e.hot_pixels, cam.width, cam.height, &k.hot);
  k.cal = cal;
  UseCameraExtras(e, &k.cal.solve);
  return k;
}

// `hot`: the known hot pixels (repaired before detection; empty when none).
std::vector<Centroid> CentroidsOf(const std::string& path, const SolveOptions& so, const DefectMap& hot) {
  if (path.size() > 4 && path.substr(path.size() - 4) == ".csv") return ReadCentroidsCsv(path);
  const Frame fr = ReadFrame(path);
  if (!hot.empty() && (fr.image.width != hot.width || fr.image.height != hot.height))
    throw InputError(path, "image size differs from the camera's");
  DetectOptions d = so.detect;
  d.saturation_adu = fr.saturation_adu;
  return CentroidsFromDetections(Detect(fr.image.view(), d, &hot), so.detector_sigma_scale);
}

// The identifier for the widest field among the guess and the aspects CalibrateCamera may try.
StarIdentifier IdentifierFor(const Opts& o, const Camera& guess) {
  Camera widest = guess;
  if (o.cal.try_aspects) {
    for (double aspect : {1.0, 0.5, 2.0}) {
      Camera alt = guess;
      alt.focal_length_y_px = guess.focal_length_px * aspect;
      if (alt.FovMaxRad() > widest.FovMaxRad()) widest = alt;
    }
  }
  return MakeIdentifierForCamera(o.catalog, widest, o.cal.fov_tolerance_pct, o.mag_max, o.source);
}

void PrintCalibration(const std::string& what, const CameraCalibration& c) {
  std::cerr << what << ": " << CalibrationStatusName(c.status) << " (" << c.message << ")\n";
  if (c.status != CalibrationStatus::kCalibrated) return;
  for (const auto& p : c.parameters)
    std::cerr << "  " << p << " = " << c.value.at(p) << " +/- " << c.sigma.at(p) << "\n";
  for (const auto& u : c.unobservable) std::cerr << "  unobservable: " << u << "\n";
  if (c.held_out_frames > 0)
    std::cerr << "  held-out frames " << c.held_out_frames << ": RMS " << c.held_out_rms_before_px
              << " px with the guess, " << c.held_out_rms_after_px << " px fitted\n";
}

void RunSingle(const Opts& o) {
  if (o.camera.empty()) throw InputError("--camera", "required (camera.json guess), or --heads heads.json");
  const Json guess_json = ReadJsonFile(o.camera);
  const Camera guess = CameraFromJson(guess_json, o.camera);
  const CameraExtras extras = CameraExtrasFromJson(guess_json, guess, o.camera);
  const Known known = KnownOf(extras, guess, o.cal);
  const StarIdentifier id = IdentifierFor(o, guess);
  std::vector<CalibrationFrame> frames;
  for (const auto& f : o.frames) frames.push_back({f, CentroidsOf(f, known.cal.solve, known.hot)});
  const CameraCalibration c = CalibrateCamera(id, frames, guess, known.cal);
  if (!o.json.empty()) WriteJsonFile(o.json, CameraCalibrationToJson(c));
  if (c.status == CalibrationStatus::kCalibrated) {
    Json out = CameraToJson(c.camera);
    AddCameraExtras(extras, &out);
    WriteJsonFile(o.out, out);
  }
  PrintCalibration("calibrate", c);
  if (c.status != CalibrationStatus::kCalibrated) throw InputError(o.out, "not written: " + c.message);
}

void RunHeads(const Opts& o) {
  const std::vector<OpticalHead> hs = ReadHeadsFile(o.heads);
  const size_t nh = hs.size();
  if (o.frames.size() % nh != 0)
    throw InputError(o.heads, "lists " + std::to_string(nh) + " heads: give frames in groups of " + std::to_string(nh) +
                                  " (one per head, in heads.json order, epoch by epoch)");
  const size_t ne = o.frames.size() / nh;
  std::vector<Camera> cams;
  std::vector<Quat> mounts;
  for (const OpticalHead& h : hs) {
    cams.push_back(h.camera);
    mounts.push_back(h.q_body_from_sensor);
  }
  std::vector<CameraCalibration> cals;
  std::vector<std::vector<AttitudeSolution>> att(ne, std::vector<AttitudeSolution>(nh));
  for (size_t h = 0; h < nh; ++h) {
    const StarIdentifier id = IdentifierFor(o, cams[h]);
    const Known known = KnownOf(hs[h].extras, cams[h], o.cal);
    std::vector<CalibrationFrame> frames;
    for (size_t e = 0; e < ne; ++e)
      frames.push_back({o.frames[e * nh + h], CentroidsOf(o.frames[e * nh + h], known.cal.solve, known.hot)});
    cals.push_back(CalibrateCamera(id, frames, cams[h], known.cal));
    for (size_t e = 0; e < ne; ++e) {
      const CalibratedFrame& f = cals.back().frames[e];
      att[e][h].status = f.status;
      att[e][h].q_inertial_from_sensor = f.q_inertial_from_sensor;
      att[e][h].covariance_rad2 = f.covariance_rad2;
    }
  }
  const HeadAlignment al = AlignHeads(att, mounts);
  Json out = Json::array(), report;
  Json heads = Json::array();
  for (size_t h = 0; h < nh; ++h) {
    const Camera& c = cals[h].status == CalibrationStatus::kCalibrated ? cals[h].camera : cams[h];
    const auto q = ToWxyz(al.q_body_sensor[h]);
    Json camera = CameraToJson(c);
    AddCameraExtras(hs[h].extras, &camera);
    out.push_back({{"camera", camera}, {"q_body_sensor", {q[0], q[1], q[2], q[3]}}});
    Json r = CameraCalibrationToJson(cals[h]);
    const Mat3& p = al.covariance_rad2[h];
    r["q_body_sensor"] = {q[0], q[1], q[2], q[3]};
    r["q_body_sensor_sigma_arcsec"] = {std::sqrt(p(0, 0)) * kRadToArcsec, std::sqrt(p(1, 1)) * kRadToArcsec,
                                       std::sqrt(p(2, 2)) * kRadToArcsec};
    r["alignment_epochs"] = al.epochs_used[h];
    r["alignment_chi2_per_dof"] = al.chi2_per_dof[h];
    heads.push_back(r);
    PrintCalibration("head " + std::to_string(h), cals[h]);
    if (h > 0)
      std::cerr << "  q_body_sensor relative to head 0 from " << al.epochs_used[h] << " epochs, sigma "
                << r["q_body_sensor_sigma_arcsec"].dump() << " arcsec\n";
  }
  report["heads"] = heads;
  if (!o.json.empty()) WriteJsonFile(o.json, report);
  WriteJsonFile(o.out, out);
}

SSIU_REGISTER_COMMAND(calibrate, [](CLI::App& root) {
  auto* cmd = root.add_subcommand("calibrate",
                                  "Fit the camera (fx, fy, principal point, distortion) to solved star frames; with "
                                  "--heads also each head's alignment");
  auto o = std::make_shared<Opts>();
  cmd->add_option("frames", o->frames,
                  "Frames (PNG/TIFF/FITS/JPEG/BMP) or centroid CSVs; with --heads one per head, epoch by epoch")
      ->required();
  cmd->add_option("--camera", o->camera, "camera.json: the guess (e.g. from the lens focal length and pixel pitch)");
  cmd->add_option("--heads", o->heads, "heads.json: each head's camera guess and q_body_sensor (head 0's is kept)");
  cmd->add_option("--out", o->out, "Fitted camera.json (with --heads: heads.json)")->required();
  cmd->add_option("--json", o->json,
                  "Report JSON (parameters, sigmas, covariance, held-out residuals, frames), - for stdout");
  cmd->add_option("--fov-tolerance-pct", o->cal.fov_tolerance_pct,
                  "Focal length of the guess known to +/- this percent")
      ->capture_default_str();
  cmd->add_option("--rounds", o->cal.rounds, "Solve-and-fit rounds")->capture_default_str();
  cmd->add_option("--holdout-every", o->cal.holdout_every,
                  "Every n-th solved frame held out for the residuals (0 = none)")
      ->capture_default_str();
  cmd->add_option("--significance-sigmas", o->cal.significance_sigmas, "Distortion terms kept above this significance")
      ->capture_default_str();
  cmd->add_option("--catalog", o->catalog, "Solver catalog directory (built there if absent; default: cache)");
  cmd->add_option("--mag-max", o->mag_max, "Catalog magnitude limit when it is built (0 = from the FOV)");
  cmd->add_option("--source", o->source, "Source catalog when it is built (default: by FOV)");
  cmd->add_option("--threshold-sigma", o->cal.solve.detect.threshold_sigma, "Detection threshold")
      ->capture_default_str();
  cmd->add_option("--systematic-px", o->cal.solve.identify.systematic_px, "Unmodelled position error while solving")
      ->capture_default_str();
  cmd->callback([o] {
    if (o->heads.empty()) {
      RunSingle(*o);
    } else {
      RunHeads(*o);
    }
  });
});

}  // namespace
}  // namespace ssiu::cli
