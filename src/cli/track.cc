// `ssiu track`: a sequence of frames; lost in space on the first, then tracking from the previous
// attitude and rate, falling back to lost in space when the lock is lost.
#include <cmath>
#include <iostream>
#include <memory>

#include "attitude/solve_adm.h"
#include "attitude/star_solver.h"
#include "cli/adm_flags.h"
#include "cli/command.h"
#include "cli/sky_flags.h"
#include "cli/smear_flags.h"
#include "core/error.h"

namespace ssiu::cli {
namespace {

struct Opts {
  std::vector<std::string> frames;
  std::string camera, catalog, json = "-", dark;
  double dt_s = 1.0;
  SolveOptions solve;
  SmearFlags smear;  // one rate for the whole sequence
  SkyFlags sky;      // the first frame's time (frame k at + k * dt); one velocity
  AdmFlags adm;
};

SSIU_REGISTER_COMMAND(track, [](CLI::App& root) {
  auto* cmd = root.add_subcommand("track", "Attitude of a frame sequence: lost in space, then tracking");
  auto o = std::make_shared<Opts>();
  cmd->add_option("frames", o->frames, "Frames in time order")->required();
  cmd->add_option("--camera", o->camera, "camera.json")->required();
  cmd->add_option("--catalog", o->catalog, "Solver catalog directory (built there if absent; default: cache)");
  cmd->add_option("--json", o->json, "Output JSON (list of per-frame results), - for stdout")->capture_default_str();
  cmd->add_option("--dt-s", o->dt_s, "Time between frames (s)")->capture_default_str();
  cmd->add_option("--dark", o->dark, "Dark/median frame subtracted before detection");
  cmd->add_option("--fov-tolerance-pct", o->solve.identify.fov_tolerance_pct,
                  "Focal length uncertainty (%), first frame");
  cmd->add_option("--search-radius-px", o->solve.track_search_radius_px, "Tracking search radius")
      ->capture_default_str();
  cmd->add_option("--systematic-px", o->solve.identify.systematic_px, "Unmodelled position error")
      ->capture_default_str();
  AddSmearFlags(cmd, &o->smear, "sensor axes, the same for every frame");
  AddSkyFlags(cmd, &o->sky);
  AddAdmFlags(cmd, &o->adm, "the solved attitudes (sensor frame AST_1; needs --time or DATE-OBS)",
              "each solution's covariance, QUEST");
  cmd->callback([o] {
    if (!(o->dt_s > 0) || !std::isfinite(o->dt_s)) throw InputError("--dt-s", "must be a finite number > 0");
    const Json cam_json = ReadJsonFile(o->camera);
    const Camera cam = CameraFromJson(cam_json, o->camera);
    // camera.json's known hot pixels, vignetting and PSF, used as `ssiu solve` uses them.
    const CameraExtras extras = CameraExtrasFromJson(cam_json, cam, o->camera);
    DefectMap hot;
    MarkHotPixels(extras.hot_pixels, cam.width, cam.height, &hot);
    const ExpectedSmear smear = SmearFromFlags(o->smear, &cam);
    const StarIdentifier id = MakeIdentifierForCamera(o->catalog, cam, o->solve.identify.fov_tolerance_pct);
    std::unique_ptr<Tracker> tracker;  // made at the first frame, whose DATE-OBS may give the time
    Frame dark;
    if (!o->dark.empty()) dark = ReadFrame(o->dark);
    Json out = Json::array();
    std::vector<TimedAttitude> timed;  // for --aem/--acm
    UtcTime t0;                        // the first frame's time, when known
    int solved = 0, tracked = 0;
    for (size_t k = 0; k < o->frames.size(); ++k) {
      const Frame fr = o->dark.empty() ? ReadFrame(o->frames[k]) : SubtractDark(ReadFrame(o->frames[k]), dark);
      if (fr.image.width != cam.width || fr.image.height != cam.height)
        throw InputError(o->frames[k], "image size differs from " + o->camera);
      DetectOptions dopt = o->solve.detect;
      UseCameraExtras(extras, &dopt);
      dopt.saturation_adu = fr.saturation_adu;
      dopt.smear = smear;
      if (dopt.gain_e_per_adu == 0) dopt.gain_e_per_adu = cam.gain_e_per_adu;
      const Detections det = Detect(fr.image.view(), dopt, &hot);
      if (!tracker) {
        SolveOptions so = o->solve;
        UseCameraExtras(extras, &so);
        so.sky = SkyFromFlags(o->sky, &fr);
        tracker = std::make_unique<Tracker>(id, cam, so);
        t0 = so.sky.time;
      }
      SolveResult r = tracker->Update(CentroidsFromDetections(det, o->solve.detector_sigma_scale), k * o->dt_s);
      r.timing_ms["detect"] = det.timing_ms.count("total") ? det.timing_ms.at("total") : 0.0;
      Json j = SolveResultToJson(r);
      j["frame"] = o->frames[k];
      j["t_s"] = k * o->dt_s;
      out.push_back(j);
      if (o->adm.given()) timed.push_back({t0.valid() ? AddSeconds(t0, k * o->dt_s) : UtcTime{}, r.attitude});
      solved += r.status == SolveStatus::kSolved;
      tracked += r.mode == SolveMode::kTracking && r.status == SolveStatus::kSolved;
    }
    WriteJsonFile(o->json, out);
    if (o->adm.given()) WriteAdmOutputs(o->adm, SolvedAttitudeHistory(timed, "--aem/--acm"));
    std::cerr << "track: " << solved << "/" << o->frames.size() << " solved, " << tracked << " by tracking\n";
  });
});

}  // namespace
}  // namespace ssiu::cli
