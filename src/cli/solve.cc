// `ssiu solve`: a frame (or a centroid CSV) -> verified star identification -> attitude JSON,
// optionally an overlay PNG and a FITS TAN WCS header; `--heads` fuses up to three optical heads;
// many inputs (or a batch flag) make a batch: one process, one catalog, many threads (cli/batch.h).
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <memory>
#include <mutex>

#include "attitude/overlay.h"
#include "attitude/solve_adm.h"
#include "attitude/star_solver.h"
#include "cli/adm_flags.h"
#include "cli/batch.h"
#include "cli/command.h"
#include "cli/sky_flags.h"
#include "cli/smear_flags.h"
#include "core/attitude.h"
#include "core/error.h"
#include "core/heads.h"
#include "core/image.h"
#include "core/output.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::vector<std::string> frames;     // frames, or centroid lists (*.csv)
  std::vector<std::string> centroids;  // --centroids, may be repeated
  std::string camera, catalog, json = "-", overlay, wcs, heads, dark;
  SolveOptions solve;
  double mag_max = 0;
  std::string source;
  SmearFlags smear;  // sensor axes; body axes with --heads
  SkyFlags sky;      // one time and velocity for every head
  BatchFlags batch;
  AdmFlags adm;  // a batch's solutions at their frames' times
  CLI::Option* json_opt = nullptr;
  std::vector<double> fov_range_deg;  // --fov-range-deg MIN,MAX: unknown field of view
};

void AddSolverFlags(CLI::App* cmd, Opts* o) {
  cmd->add_option("--fov-tolerance-pct", o->solve.identify.fov_tolerance_pct,
                  "Focal length known to +/- this percent: search and refine it");
  cmd->add_option("--fov-range-deg", o->fov_range_deg,
                  "Unknown field of view: search the horizontal FOV in MIN,MAX deg and fit the focal length "
                  "(camera.json then needs no focal length; a given one is ignored)")
      ->expected(2)
      ->delimiter(',');
  cmd->add_option("--max-false-prob", o->solve.identify.max_false_match_prob, "Accept below this chance probability")
      ->capture_default_str();
  cmd->add_option("--refine-focal-p", o->solve.identify.refine_focal_p,
                  "Lost in space with a fixed focal length: refit it with the attitude when the stars reject the "
                  "camera's at this p-value (F-test; 0 = keep the camera's)")
      ->capture_default_str();
  cmd->add_option("--refine-principal-p", o->solve.identify.refine_principal_p,
                  "And the principal point, with 12+ stars across the field, at this p-value (F-test of (cx, cy); "
                  "0 = keep the camera's)")
      ->capture_default_str();
  cmd->add_flag_callback(
      "--no-photometry", [o] { o->solve.identify.use_photometry = false; },
      "Lost in space: leave the centroids' fluxes out of the chance probability (geometry only)");
  cmd->add_option("--max-hypotheses", o->solve.identify.max_hypotheses,
                  "Lost in space: give up (no_match) after this many hypotheses (the deterministic work budget)")
      ->capture_default_str();
  cmd->add_option("--max-patterns", o->solve.identify.max_patterns,
                  "Lost in space: give up (no_match) after this many centroid triangles looked up")
      ->capture_default_str();
  cmd->add_option("--timeout-ms", o->solve.identify.timeout_ms,
                  "Lost in space: also stop after this much CPU time, no_match (0 = no limit; the answer then "
                  "depends on the processor)")
      ->capture_default_str();
  cmd->add_option("--centroid-sigma-px", o->solve.identify.centroid_sigma_px, "Centroid noise when not measured")
      ->capture_default_str();
  cmd->add_option("--systematic-px", o->solve.identify.systematic_px, "Unmodelled position error (distortion)")
      ->capture_default_str();
  cmd->add_option("--threshold-sigma", o->solve.detect.threshold_sigma, "Detection threshold")->capture_default_str();
  cmd->add_option("--mag-max", o->mag_max, "Catalog magnitude limit when it is built (0 = from the FOV)");
  cmd->add_option("--source", o->source, "Source catalog when it is built (default: by FOV)");
}

StarIdentifier MakeIdentifier(const Opts& o, const Camera& cam) {
  return MakeIdentifierFor(o.catalog, cam, o.solve.identify, o.mag_max, o.source);
}

// --camera (with --fov-range-deg it may lack a focal length) and what it gives beyond the geometry:
// its known hot pixels, repaired before detection, and its vignetting, taken out of the fluxes.
struct SolveCamera {
  Camera cam;
  DefectMap hot;  // empty when camera.json lists none
  CameraExtras extras;
};
SolveCamera LoadSolveCamera(const Opts& o) {
  if (o.camera.empty()) throw InputError("--camera", "required (camera.json)");
  const IdentifyOptions& io = o.solve.identify;
  const Json j = ReadJsonFile(o.camera);
  SolveCamera s;
  s.cam = CameraFromJson(j, o.camera, io.FovRange() ? std::sqrt(io.fov_min_deg * io.fov_max_deg) : 0.0);
  s.extras = CameraExtrasFromJson(j, s.cam, o.camera);
  MarkHotPixels(s.extras.hot_pixels, s.cam.width, s.cam.height, &s.hot);
  return s;
}

void PrintSummary(const std::string& what, const SolveResult& r) {
  std::cerr << what << ": " << SolveStatusName(r.status);
  if (r.status == SolveStatus::kSolved) {
    const RaDecRoll a = RaDecRollFromQuat(r.attitude.q_inertial_from_sensor);
    std::cerr << " ra " << a.ra_rad * kRadToDeg << " dec " << a.dec_rad * kRadToDeg << " roll "
              << a.roll_rad * kRadToDeg << " deg, " << r.identification.matches.size() << " stars";
  }
  std::cerr << " (" << r.message << ")\n";
}

// One input: a frame (dark-subtracted when `dark`), kept in *fr for the overlay, or a centroid list.
SolveResult SolveInput(const Opts& o, const StarIdentifier& id, const SolveCamera& sc, const std::string& path,
                       bool centroids, const Frame* dark, Frame* fr) {
  const Camera& cam = sc.cam;
  SolveOptions so = o.solve;
  UseCameraExtras(sc.extras, &so);
  if (centroids) {
    RefuseSmearFlags(o.smear, "needs a frame, not --centroids");
    so.sky = SkyFromFlags(o.sky, nullptr);
    return SolveCentroids(id, ReadCentroidsCsv(path), cam, so);
  }
  *fr = dark ? SubtractDark(ReadFrame(path), *dark) : ReadFrame(path);
  so.detect.saturation_adu = fr->saturation_adu;
  so.detect.smear = SmearFromFlags(o.smear, &cam);
  so.sky = SkyFromFlags(o.sky, fr);
  return SolveFrame(id, fr->image.view(), cam, so, &sc.hot);
}

void RunSingle(const Opts& o) {
  const SolveCamera sc = LoadSolveCamera(o);
  const Camera& cam = sc.cam;
  const StarIdentifier id = MakeIdentifier(o, cam);
  Frame fr;
  const bool centroids = !o.centroids.empty() || IsCentroidCsv(o.frames.at(0));
  const std::string& input = o.centroids.empty() ? o.frames[0] : o.centroids[0];
  const Frame dark = centroids || o.dark.empty() ? Frame{} : ReadFrame(o.dark);
  const SolveResult r = SolveInput(o, id, sc, input, centroids, o.dark.empty() ? nullptr : &dark, &fr);
  // Every output is written before the summary line, so that an unwritable one is the only message.
  WriteJsonFile(o.json, SolveResultToJson(r));
  if (o.adm.given()) WriteAdmOutputs(o.adm, SolvedAttitudeHistory({{r.sky.time, r.attitude}}, "--aem/--acm"));
  if (!o.overlay.empty()) {
    if (fr.image.pixels.empty()) throw InputError(o.overlay, "--overlay needs a frame, not --centroids");
    WriteSolveOverlay(o.overlay, fr.image.view(), cam, id, r);
  }
  if (!o.wcs.empty() && r.status == SolveStatus::kSolved) {
    const Camera c = FittedCamera(cam, r.identification);
    WriteFileAtomic(o.wcs, TanWcsHeader(r.attitude.q_inertial_from_sensor, c));
  }
  PrintSummary(input, r);
}

// --csv columns of a batch (docs/identify.md "Batch"); the cells come from the record's JSON.
const std::vector<std::string> kBatchColumns = {"file",
                                                "status",
                                                "mode",
                                                "ra_deg",
                                                "dec_deg",
                                                "roll_deg",
                                                "q_w",
                                                "q_x",
                                                "q_y",
                                                "q_z",
                                                "sigma_cross_arcsec",
                                                "sigma_roll_arcsec",
                                                "focal_length_px",
                                                "num_centroids",
                                                "num_matches",
                                                "false_match_probability",
                                                "time_ms",
                                                "message"};

std::vector<std::string> BatchRow(const std::string& file, const Json& j) {
  const Json& q = j["q"];
  double time_ms = 0;  // detect + identify + attitude
  for (const auto& [k, v] : j["timing_ms"].items()) time_ms += v.get<double>();
  return {CsvText(file),
          CsvText(j["status"]),
          CsvText(j["mode"]),
          CsvNumber(j["ra_deg"]),
          CsvNumber(j["dec_deg"]),
          CsvNumber(j["roll_deg"]),
          CsvNumber(q.is_array() ? q[0] : Json()),
          CsvNumber(q.is_array() ? q[1] : Json()),
          CsvNumber(q.is_array() ? q[2] : Json()),
          CsvNumber(q.is_array() ? q[3] : Json()),
          CsvNumber(j["sigma_cross_arcsec"]),
          CsvNumber(j["sigma_roll_arcsec"]),
          CsvNumber(j["focal_length_px"]),
          CsvNumber(j["num_centroids"]),
          CsvNumber(j["matches"].size()),
          CsvNumber(j["false_match_probability"]),
          CsvNumber(time_ms),
          CsvText(j["message"])};
}

// Many inputs, one catalog: every input is solved as a single `ssiu solve` of it would be.
void RunBatchSolve(const Opts& o, const std::vector<std::string>& inputs) {
  if (o.json_opt->count() > 0) throw InputError("--json", "is one input's output: a batch writes --jsonl and/or --csv");
  if (!o.overlay.empty() || !o.wcs.empty()) {
    throw InputError(o.overlay.empty() ? "--wcs" : "--overlay", "is one frame's output: not in a batch");
  }
  const SolveCamera sc = LoadSolveCamera(o);
  const StarIdentifier id = MakeIdentifier(o, sc.cam);
  const Frame dark = o.dark.empty() ? Frame{} : ReadFrame(o.dark);
  std::mutex timed_mutex;
  std::vector<TimedAttitude> timed;  // for --aem/--acm: each solution at its frame's time
  auto write_adm = [&] {
    if (o.adm.given()) WriteAdmOutputs(o.adm, SolvedAttitudeHistory(timed, "--aem/--acm"));
  };
  try {
    RunBatch("ssiu solve", inputs, o.batch, kBatchColumns, [&](const std::string& input) {
      Frame fr;
      const bool centroids = IsCentroidCsv(input);
      const SolveResult r = SolveInput(o, id, sc, input, centroids, o.dark.empty() ? nullptr : &dark, &fr);
      if (o.adm.given()) {
        std::lock_guard<std::mutex> lock(timed_mutex);
        timed.push_back({r.sky.time, r.attitude});
      }
      Json j = SolveResultToJson(r);
      return BatchRecord{j, BatchRow(input, j)};
    });
  } catch (const InputError&) {
    try {  // the inputs that solved, as their records were written; then the batch's own error
      write_adm();
    } catch (const InputError&) {
    }
    throw;
  }
  write_adm();
}

void RunHeads(const Opts& o) {
  const std::vector<OpticalHead> hs = ReadHeadsFile(o.heads);
  if (o.frames.size() != hs.size())
    throw InputError(o.heads, "lists " + std::to_string(hs.size()) + " heads but " + std::to_string(o.frames.size()) +
                                  " frames were given");
  // --rate-dps is the body's rate here: each head sees it in its own axes (as the unit's processor
  // hands the gyro rate to each head).
  const Vec3 w_body_rad_s = o.smear.given() ? SmearRateRadS(o.smear, true) : Vec3::Zero();
  if (!o.smear.given()) RefuseSmearFlags(o.smear, "given without --rate-dps");
  std::vector<Identification> ids;
  std::vector<SolveResult> results;  // summaries printed after the output is written
  std::vector<Quat> mounts;
  Json heads = Json::array();
  double heads_ms = 0;  // read excluded: detect + identify + attitude of every head
  for (size_t h = 0; h < hs.size(); ++h) {
    const Camera& cam = hs[h].camera;
    mounts.push_back(hs[h].q_body_from_sensor);
    const StarIdentifier id = MakeIdentifier(o, cam);
    const Frame fr = ReadFrame(o.frames[h]);
    DefectMap hot;  // the head's known hot pixels, vignetting and PSF, as for one camera
    MarkHotPixels(hs[h].extras.hot_pixels, cam.width, cam.height, &hot);
    SolveOptions so = o.solve;
    UseCameraExtras(hs[h].extras, &so);
    so.detect.saturation_adu = fr.saturation_adu;
    so.sky = SkyFromFlags(o.sky, &fr);
    if (o.smear.given()) {
      so.detect.smear = SmearModel(mounts.back().normalized().conjugate() * w_body_rad_s, o.smear.exposure_s, cam);
    }
    const SolveResult r = SolveFrame(id, fr.image.view(), cam, so, &hot);
    results.push_back(r);
    heads.push_back(SolveResultToJson(r));
    for (const auto& [k, v] : r.timing_ms) heads_ms += v;
    ids.push_back(r.identification);
  }
  const auto t_fuse = std::chrono::steady_clock::now();
  const MultiHeadSolution mh = SolveMultiHeadChecked(ids, mounts);
  const double fuse_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_fuse).count();
  const AttitudeSolution& s = mh.attitude;
  // The JSON contract of a single-head solve, for the body attitude (inertial <- body, "frame": "body");
  // per-head results under "heads", each with "use": used / inconsistent / its own status.
  Json j;
  j["status"] = SolveStatusName(s.status);
  j["mode"] = "lost_in_space";
  j["frame"] = "body";
  j["message"] = mh.message;
  const bool ok = s.status == SolveStatus::kSolved;
  const RaDecRoll a = RaDecRollFromQuat(s.q_inertial_from_sensor);
  if (ok) {
    const auto q = ToWxyz(s.q_inertial_from_sensor);
    j["q"] = {q[0], q[1], q[2], q[3]};
  } else {
    j["q"] = nullptr;
  }
  auto num = [ok](double v) { return ok ? Json(v) : Json(nullptr); };
  j["ra_deg"] = num(a.ra_rad * kRadToDeg);
  j["dec_deg"] = num(a.dec_rad * kRadToDeg);
  j["roll_deg"] = num(a.roll_rad * kRadToDeg);
  j["sigma_cross_arcsec"] = num(s.sigma_cross_rad * kRadToArcsec);
  j["sigma_roll_arcsec"] = num(s.sigma_roll_rad * kRadToArcsec);
  j["focal_length_px"] = nullptr;  // one per head, under "heads"
  j["focal_length_y_px"] = nullptr;
  j["false_match_probability"] = mh.false_match_probability;
  Json matches = Json::array();
  for (size_t h = 0; h < ids.size(); ++h) {
    heads[h]["use"] = HeadUseName(mh.head_use[h], ids[h].status);
    if (!ok || mh.head_use[h] != HeadUse::kUsed) continue;
    const Mat3 rm = mounts[h].normalized().toRotationMatrix();
    for (const auto& m : ids[h].matches) {
      const Vec3 pred = s.q_inertial_from_sensor.conjugate() * m.r_inertial;  // body axes
      const Vec3 b = rm * m.b_sensor;
      const double res = std::atan2(pred.cross(b).norm(), pred.dot(b));
      matches.push_back({{"head", h},
                         {"x_px", m.x_px},
                         {"y_px", m.y_px},
                         {"star_id", m.star_id},
                         {"mag", m.mag},
                         {"residual_arcsec", res * kRadToArcsec}});
    }
  }
  j["matches"] = matches;
  j["num_stars"] = s.num_observations;
  j["timing_ms"] = {{"heads", heads_ms}, {"fuse", fuse_ms}};
  j["heads"] = heads;
  if (!results.empty())  // every head has the one time and velocity
    AddCorrectionsToJson(results[0].sky, results[0].catalog_epoch_year, ok ? &s.q_inertial_from_sensor : nullptr, &j);
  WriteJsonFile(o.json, j);
  for (size_t h = 0; h < results.size(); ++h) PrintSummary(o.frames[h], results[h]);
}

SSIU_REGISTER_COMMAND(solve, [](CLI::App& root) {
  auto* cmd = root.add_subcommand("solve", "Lost-in-space attitude from a star frame (or centroids)");
  auto o = std::make_shared<Opts>();
  cmd->add_option(
      "frames", o->frames,
      "Frames (PNG/TIFF/FITS/JPEG/BMP) or centroid lists (*.csv); more than one is a batch; with --heads one "
      "frame per head");
  cmd->add_option("--camera", o->camera, "camera.json");
  cmd->add_option("--catalog", o->catalog, "Solver catalog directory (built there if absent; default: cache)");
  cmd->add_option("--centroids", o->centroids,
                  "CSV x_px,y_px[,flux][,sigma_px] instead of a frame (repeat for a batch)")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  o->json_opt = cmd->add_option("--json", o->json, "Output JSON of one input, - for stdout")->capture_default_str();
  cmd->add_option("--overlay", o->overlay, "Overlay PNG (FILE.png) with detected, matched and rejected objects");
  cmd->add_option("--wcs", o->wcs, "FITS TAN WCS header of the solution (TAN-SIP when the camera has distortion)");
  cmd->add_option("--heads", o->heads, "heads.json: up to three heads, fused into one body attitude");
  cmd->add_option("--dark", o->dark, "Dark/median frame subtracted before detection");
  AddSolverFlags(cmd, o.get());
  AddSmearFlags(cmd, &o->smear, "sensor axes (with --heads: body axes)");
  AddSkyFlags(cmd, &o->sky);
  AddBatchFlags(cmd, &o->batch, "the --json of that input");
  AddAdmFlags(cmd, &o->adm, "the solutions at their frames' times (FITS DATE-OBS or --time), sensor frame AST_1",
              "each solution's covariance, QUEST");
  cmd->footer(
      "Batch: `ssiu solve F1.png F2.fits C3.csv ... --camera CAM --jsonl OUT.jsonl [--csv OUT.csv] [--threads N]`\n"
      "  Inputs: positional (frames; names ending in .csv are centroid lists), then --centroids (repeatable),\n"
      "  then the lines of --list FILE. One camera and catalog for all. Exit status 1 when any input failed\n"
      "  (its record has status \"error\"), after every input was processed. --csv columns: " +
      CsvJoin(kBatchColumns) +
      "\n  (q_* the quaternion w,x,y,z; time_ms detect + identify + attitude; empty cells when unsolved).");
  cmd->callback([o] {
    // Usage checked before any work. The one place that decides how many frames a solve takes:
    // with --heads the frames are the heads of one unit; otherwise several inputs (or a batch flag)
    // are a batch, each input solved on its own.
    if (!o->overlay.empty()) CheckPngOutputName(o->overlay);
    if (!o->fov_range_deg.empty()) {
      if (o->solve.identify.fov_tolerance_pct > 0)
        throw InputError("--fov-range-deg", "give --fov-range-deg or --fov-tolerance-pct, not both");
      const double lo = o->fov_range_deg[0], hi = o->fov_range_deg[1];
      if (!(lo > 0.5 && lo < hi && hi < 90))
        throw InputError("--fov-range-deg", "must be MIN,MAX with 0.5 < MIN < MAX < 90 deg");
      o->solve.identify.fov_min_deg = lo;
      o->solve.identify.fov_max_deg = hi;
    }
    if (!o->heads.empty()) {
      if (o->batch.given() || !o->centroids.empty()) {
        throw InputError("--heads", "takes one frame per head: not with --centroids, --list, --jsonl or --csv");
      }
      if (o->adm.given())
        throw InputError(o->adm.aem.empty() ? "--acm" : "--aem", "not with --heads (one body attitude)");
      RunHeads(*o);
      return;
    }
    std::vector<std::string> inputs = o->frames;
    inputs.insert(inputs.end(), o->centroids.begin(), o->centroids.end());
    inputs = BatchInputs(inputs, o->batch);
    if (inputs.size() == 1 && !o->batch.given()) {
      RunSingle(*o);
    } else if (inputs.empty()) {
      throw InputError("ssiu solve", "give a FRAME or --centroids FILE.csv");
    } else {
      RunBatchSolve(*o, inputs);
    }
  });
});

}  // namespace
}  // namespace ssiu::cli
