#include "sim/demo.h"

#include <cstdio>

#include "attitude/star_solver.h"
#include "core/attitude.h"
#include "core/camera.h"
#include "detect/detect.h"
#include "sim/detection_score.h"
#include "sim/frame_sim.h"

namespace ssiu {

DemoReport RunDemo(const StarCatalog& catalog, uint64_t seed) {
  const Camera cam;
  const FrameSimOptions so;
  const Quat q = RandomAttitude(seed);
  const SimulatedFrame f = SimulateFrame(cam, catalog, q, so, seed);
  const Detections d = Detect(f.image.view(), DetectOptionsForSimulation(cam, so, /*give_rate=*/true));
  const DetectionScore sc = ScoreDetections(f, d);
  const RaDecRoll rdr = RaDecRollFromQuat(q);
  const double fov_deg = cam.FovXRad() * kRadToDeg;
  const double arcsec_per_px = fov_deg * 3600.0 / cam.width;

  // Lost-in-space solve of the same frame, as the unit would do it.
  const StarIdentifier id = MakeIdentifierForCamera("", cam, 0.0);
  const SolveResult sr = SolveFrame(id, f.image.view(), cam, SolveOptions{});

  char buf[4096];
  int n = std::snprintf(
      buf, sizeof(buf),
      "ssiu demo (seed %llu): simulated %dx%d frame, FOV %.1f deg, true attitude RA %.4f Dec %.4f roll %.4f deg\n"
      "  truth: %zu catalog stars drawn (V <= %.1f), %d hot pixels, %d cosmic rays\n"
      "  detect: %zu stars reported, %zu objects rejected, background %.1f ADU, noise %.2f ADU, %.2f ms\n"
      "  recall: %d of %d stars with SNR >= 10 found (%.1f%%); %d false detections\n"
      "  centroid error (SNR >= 20, %d stars): %.3f px RMS per axis = %.2f arcsec\n",
      static_cast<unsigned long long>(seed), cam.width, cam.height, fov_deg, rdr.ra_rad * kRadToDeg,
      rdr.dec_rad * kRadToDeg, rdr.roll_rad * kRadToDeg, f.stars.size(), so.mag_max, so.hot_pixels, so.cosmic_rays,
      d.stars.size(), d.rejected.size(), d.background_adu, d.noise_adu, d.timing_ms.at("total"), sc.found_snr10,
      sc.true_stars_snr10, sc.true_stars_snr10 ? 100.0 * sc.found_snr10 / sc.true_stars_snr10 : 100.0,
      sc.false_detections, sc.centroid_count, sc.centroid_rms_px, sc.centroid_rms_px * arcsec_per_px);
  DemoReport r;
  const auto w = ToWxyz(q);
  r.json = {{"seed", seed},
            {"q_true", {w[0], w[1], w[2], w[3]}},
            {"stars_drawn", f.stars.size()},
            {"stars_reported", d.stars.size()},
            {"recall_snr10", sc.true_stars_snr10 ? double(sc.found_snr10) / sc.true_stars_snr10 : 1.0},
            {"false_detections", sc.false_detections},
            {"centroid_rms_px", sc.centroid_rms_px},
            {"centroid_rms_arcsec", sc.centroid_rms_px * arcsec_per_px},
            {"detect_ms", d.timing_ms.at("total")},
            {"status", SolveStatusName(sr.status)}};
  if (sr.status == SolveStatus::kSolved) {
    const Quat qe = sr.attitude.q_inertial_from_sensor;
    const RaDecRoll e = RaDecRollFromQuat(qe);
    const AttitudeErrorSplit err = SplitAttitudeError(qe, q);
    const auto we = ToWxyz(qe);
    n += std::snprintf(
        buf + n, sizeof(buf) - n,
        "  solve: %s, %zu stars matched, false-match probability %.1e\n"
        "  attitude q = [%.8f, %.8f, %.8f, %.8f]: RA %.4f Dec %.4f roll %.4f deg\n"
        "  error vs truth: %.2f arcsec (cross-boresight %.2f, roll %.2f); reported 1-sigma %.2f / %.2f arcsec\n",
        SolveStatusName(sr.status), sr.identification.matches.size(), sr.identification.false_match_probability, we[0],
        we[1], we[2], we[3], e.ra_rad * kRadToDeg, e.dec_rad * kRadToDeg, e.roll_rad * kRadToDeg,
        err.total_rad * kRadToArcsec, err.cross_rad * kRadToArcsec, err.roll_rad * kRadToArcsec,
        sr.attitude.sigma_cross_rad * kRadToArcsec, sr.attitude.sigma_roll_rad * kRadToArcsec);
    r.json["q"] = {we[0], we[1], we[2], we[3]};
    r.json["error_arcsec"] = err.total_rad * kRadToArcsec;
    r.json["error_cross_arcsec"] = err.cross_rad * kRadToArcsec;
    r.json["error_roll_arcsec"] = err.roll_rad * kRadToArcsec;
  } else {
    n += std::snprintf(buf + n, sizeof(buf) - n, "  solve: %s (%s)\n", SolveStatusName(sr.status), sr.message.c_str());
  }
  r.text = buf;
  return r;
}

}  // namespace ssiu
