// `ssiu discover gyro LOG.csv [LOG2.csv ...] --json OUT` and `ssiu discover frames FRAME... --camera
// CAM.json --json OUT`: model discrepancy analysis (docs/discrepancy.md). The library does the work
// (discover/discover_gyro.h, discover/discover_frames.h); this file parses flags and writes JSON.
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "calibration/allan_io.h"
#include "cli/command.h"
#include "core/camera.h"
#include "core/error.h"
#include "core/image.h"
#include "core/json.h"
#include "discover/discover_allan.h"
#include "discover/discover_frames.h"
#include "discover/discover_gyro.h"
#include "discover/frame_compare.h"

namespace {

struct GyroOpts {
  std::vector<std::string> logs;
  std::string json;
  ssiu::GyroDiscoverOptions opt;
};

struct FrameOpts {
  std::vector<std::string> frames;
  std::string camera, json, plot, dark, catalog, defects, defects_out, compare_sim, sim_json;
  double psf_sigma_px = 0;  // when not given: camera.json "psf_sigma_px" if present, else not tested
  CLI::Option* psf_flag = nullptr;
  double fov_tolerance_pct = 1.0;
  ssiu::FrameDiscoverOptions opt;
};

struct AllanOpts {
  std::string curve, channel, unit, tau_file, json;
  double duration_s = 0, sample_rate_hz = 0;
  ssiu::AllanDiscrepancyOptions opt;
};

}  // namespace

SSIU_REGISTER_COMMAND(discover_allan, [](CLI::App& root) {
  auto* discover = ssiu::cli::GetOrAddSubcommand(root, "discover", "Find what the model gets wrong in measured data");
  auto* cmd = discover->add_subcommand(
      "allan",
      "Where the default gyro noise model (ARW + bias instability) leaves a measured Allan curve, and the terms "
      "(quantization, rate_random_walk, rate_ramp) that extend it step by step (`causes`)");
  auto o = std::make_shared<AllanOpts>();
  cmd->add_option("--curve", o->curve, "Allan curve file (as for `ssiu allan --curve`)")->required();
  cmd->add_option("--channel", o->channel, "Channel within the file");
  cmd->add_option("--unit", o->unit, "Rate unit of the ADEV column (rad/s, deg/s, deg/h)");
  cmd->add_option("--tau-file", o->tau_file, "Taus in a separate file (imu_utils)");
  cmd->add_option("--duration-s", o->duration_s, "Log length behind the curve (for the edf)");
  cmd->add_option("--sample-rate-hz", o->sample_rate_hz, "Sample rate behind the curve");
  cmd->add_option("--json", o->json, "Output JSON, - for stdout");
  cmd->callback([o] {
    ssiu::CurveFileOptions co;
    co.channel = o->channel;
    co.unit = o->unit;
    co.tau_file = o->tau_file;
    co.duration_s = o->duration_s;
    co.sample_rate_hz = o->sample_rate_hz;
    const ssiu::CurveFile cf = ssiu::ReadAllanCurveFile(o->curve, co);
    // Each point is weighted by its own ADEV: a zero one made every figure NaN (written as null).
    if (cf.curve.tau_s.size() < 4) throw ssiu::InputError(o->curve, "fewer than 4 Allan points");
    for (size_t i = 0; i < cf.curve.adev.size(); ++i) {
      if (!(cf.curve.adev[i] > 0)) {
        throw ssiu::InputError(o->curve, "ADEV is zero at tau " + std::to_string(cf.curve.tau_s[i]) +
                                             " s: the base model cannot be weighted there");
      }
    }
    const ssiu::AllanDiscrepancy d = ssiu::CompareAllanToDefaultModel(cf.curve, o->opt);
    const double dph = 180 / M_PI * 3600;  // rad/s -> deg/h
    ssiu::Json j;
    j["file"] = o->curve;
    j["channel"] = cf.channel;
    j["base_model"] = {{"arw_deg_per_sqrt_h", d.base_arw * dph / 60},
                       {"bias_instability_dph", d.base_bias_instability * dph}};
    j["chi2_per_dof_before"] = d.chi2_per_dof_before;
    j["chi2_per_dof_after"] = d.chi2_per_dof_after;
    j["departures_tau_s"] = ssiu::Json::array();
    for (const auto& [lo, hi] : d.departures_s) j["departures_tau_s"].push_back({lo, hi});
    j["missing_terms"] = d.missing_terms;
    const auto g = ssiu::ToGyroUnits(d.extended);
    j["extended"] = {{"arw_deg_per_sqrt_h", g.arw_deg_per_sqrt_h.value},
                     {"bias_instability_dph", g.bias_instability_dph.value},
                     {"rrw_deg_per_h_per_sqrt_h", g.rrw_deg_per_h_per_sqrt_h.value},
                     {"quantization_arcsec", g.quantization_arcsec.value},
                     {"rate_ramp_deg_per_h2", g.rate_ramp_deg_per_h2.value}};
    // The stepwise extension: the terms in the order they entered, with the final joint fit's values.
    const auto jg = ssiu::ToGyroUnits(d.joint);
    const std::map<std::string, std::pair<std::string, ssiu::NoiseTerm>> in_units = {
        {"quantization", {"quantization_arcsec", jg.quantization_arcsec}},
        {"rate_random_walk", {"rrw_deg_per_h_per_sqrt_h", jg.rrw_deg_per_h_per_sqrt_h}},
        {"rate_ramp", {"rate_ramp_deg_per_h2", jg.rate_ramp_deg_per_h2}}};
    j["causes"] = ssiu::Json::array();
    std::string chain;
    for (const auto& st : d.steps) {
      const auto& [key, term] = in_units.at(st.term);
      j["causes"].push_back({{"cause", st.term},
                             {"parameters", {{key, term.value}}},
                             {"parameter_sigmas", {{key, term.sigma}}},
                             {"p_value", st.p_value},
                             {"gain", st.gain},
                             {"gain_z", st.gain_z},
                             {"chi2_per_dof", st.chi2_per_dof},
                             {"residual_rms_pct", st.residual_rms_pct}});
      chain += (chain.empty() ? "" : " + ") + st.term;
    }
    j["joint"] = {{"arw_deg_per_sqrt_h", jg.arw_deg_per_sqrt_h.value},
                  {"arw_sigma_deg_per_sqrt_h", jg.arw_deg_per_sqrt_h.sigma},
                  {"bias_instability_dph", jg.bias_instability_dph.value},
                  {"bias_instability_sigma_dph", jg.bias_instability_dph.sigma},
                  {"chi2_per_dof", d.joint.chi2_per_dof}};
    j["residual_rms_pct_before"] = d.residual_rms_pct_before;
    j["residual_rms_pct_after"] = d.residual_rms_pct_after;
    j["point_sigma_rms_pct"] = d.point_sigma_rms_pct;
    j["correlations"] = ssiu::Json::array();
    for (const auto& c : d.correlations) j["correlations"].push_back({{"a", c.a}, {"b", c.b}, {"r", c.r}});
    j["left"] = d.left;
    j["final_departures_tau_s"] = ssiu::Json::array();
    for (const auto& [lo, hi] : d.final_departures_s) j["final_departures_tau_s"].push_back({lo, hi});
    // Output first: a path that cannot be written is then the only line printed.
    if (!o->json.empty()) ssiu::WriteJsonFile(o->json, j);
    std::cerr << "discover allan: " << o->curve << " " << cf.channel << ": chi2/dof " << d.chi2_per_dof_before << " -> "
              << d.chi2_per_dof_after << ", departs in " << d.departures_s.size() << " tau range(s); cause "
              << (chain.empty() ? "none" : chain) << (d.left == "unexplained" ? ", then unexplained" : "")
              << "; residual rms " << d.residual_rms_pct_before << " -> " << d.residual_rms_pct_after
              << " % (points' own " << d.point_sigma_rms_pct << " %)\n";
  });
});

SSIU_REGISTER_COMMAND(discover_frames, [](CLI::App& root) {
  auto* discover = ssiu::cli::GetOrAddSubcommand(root, "discover", "Find what the model gets wrong in measured data");
  auto* cmd = discover->add_subcommand(
      "frames",
      "Solve every frame, fit star residual and flux patterns, name the camera-model cause (a cause is "
      "named only within physical bounds and with a significant held-out gain; `unexplained` when the star "
      "positions or fluxes keep structure over the field that no cause explains)");
  auto o = std::make_shared<FrameOpts>();
  cmd->add_option("frames", o->frames, "Frames (PNG/TIFF/FITS/JPEG/BMP)")->required();
  cmd->add_option("--camera", o->camera, "camera.json (the model under test)")->required();
  cmd->add_option("--json", o->json, "Output JSON, - for stdout");
  cmd->add_option("--plot", o->plot, "Directory for residual quiver plots before/after");
  cmd->add_option("--dark", o->dark, "Dark/median frame subtracted before detection");
  cmd->add_option("--catalog", o->catalog, "Solver catalog directory (default: cache)");
  cmd->add_option("--fov-tolerance-pct", o->fov_tolerance_pct, "Focal length known to +/- this percent")
      ->capture_default_str();
  cmd->add_option("--alpha", o->opt.alpha, "Family-wise false-alarm probability")->capture_default_str();
  cmd->add_option("--gain-alpha", o->opt.gain_alpha,
                  "One-sided false-alarm probability of the held-out gain a named cause must show")
      ->capture_default_str();
  cmd->add_option("--residual-alpha", o->opt.residual_alpha,
                  "False-alarm probability of the residual tests behind `unexplained` (position and flux maps)")
      ->capture_default_str();
  o->psf_flag = cmd->add_option(
      "--psf-sigma-px", o->psf_sigma_px,
      "The model's PSF sigma, px (default: camera.json \"psf_sigma_px\"; absent: psf_shape not tested)");
  cmd->add_option("--defects", o->defects, "Known defect map PNG (0 good): repaired before detection, not a cause");
  cmd->add_option("--defects-out", o->defects_out, "Write the persistent hot pixels found as a defect map PNG");
  cmd->add_option("--compare-sim", o->compare_sim,
                  "Simulate every solved frame at its attitude, compare star by star with the measured frames, "
                  "then again with the extended model; JSON here (- for stdout)");
  cmd->add_option("--sim-json", o->sim_json, "Simulator options of the model under test (default: the simulator's)");
  cmd->callback([o] {
    const ssiu::Json cam_json = ssiu::ReadJsonFile(o->camera);
    const ssiu::Camera cam = ssiu::CameraFromJson(cam_json, o->camera);
    // The model beyond the geometry: camera.json's optional psf_*, vignetting, hot_pixels (--psf-sigma-px
    // overrides the PSF sigma); the known hot pixels are repaired before detection with --defects.
    const ssiu::CameraExtras extras = ssiu::CameraExtrasFromJson(cam_json, cam, o->camera);
    o->opt.psf_sigma_px = o->psf_flag->count() > 0 ? o->psf_sigma_px : extras.psf_sigma_px;
    o->opt.psf_ellipticity = extras.psf_ellipticity;
    o->opt.psf_angle_deg = extras.psf_angle_deg;
    o->opt.vignetting = extras.vignetting;
    o->opt.hot_pixels = extras.hot_pixels;
    o->opt.Check();  // before any work
    ssiu::DefectMap known;
    if (!o->defects.empty()) {
      known = ssiu::LoadDefectMap(o->defects);
      if (known.width != cam.width || known.height != cam.height)
        throw ssiu::InputError(o->defects, "defect map size differs from the camera's");
    }
    ssiu::MarkHotPixels(extras.hot_pixels, cam.width, cam.height, &known);
    ssiu::SolveOptions so;
    so.identify.fov_tolerance_pct = o->fov_tolerance_pct;
    const ssiu::StarIdentifier id = ssiu::MakeIdentifierForCamera(o->catalog, cam, o->fov_tolerance_pct);
    std::vector<ssiu::Frame> frames;
    for (const auto& f : o->frames) {
      frames.push_back(o->dark.empty() ? ssiu::ReadFrame(f)
                                       : ssiu::SubtractDark(ssiu::ReadFrame(f), ssiu::ReadFrame(o->dark)));
    }
    std::vector<ssiu::ImageView> views;
    for (const auto& f : frames) views.push_back(f.image.view());
    so.detect.saturation_adu = frames.front().saturation_adu;
    for (size_t i = 0; i < frames.size(); ++i) {
      if (frames[i].image.width != cam.width || frames[i].image.height != cam.height)
        throw ssiu::InputError(o->frames[i], "frame size differs from the camera's width/height");
    }
    const ssiu::SolvedFrameSet set =
        ssiu::SolveFrameSet(id, views, o->frames, cam, so, known.empty() ? nullptr : &known);
    const ssiu::FrameDiscovery d = ssiu::DiscoverFrames(set, cam, o->opt);
    // The summary is printed after every output is written: an unwritable path is then the only line.
    std::ostringstream summary;
    summary << "discover frames: " << d.frames_solved << "/" << d.frames << " solved, " << d.stars << " stars; cause "
            << (d.cause == "unexplained" || d.causes.empty() ? d.cause : "");
    std::string chain;  // the causes in the order they entered the model
    for (size_t k = 0; k < d.causes.size(); ++k) chain += (k ? " + " : "") + d.causes[k].cause;
    summary << (d.cause == "unexplained" ? (chain.empty() ? "" : " (after " + chain + ")") : chain);
    for (const auto& [k, v] : d.parameters) summary << " " << k << "=" << v << "+-" << d.sigmas.at(k);
    summary << "; residual rms " << d.residual_rms_before_arcsec << " -> " << d.residual_rms_after_arcsec
            << " arcsec (gain " << d.gain << ")\n";
    if (d.cause == "unexplained") {
      const ssiu::FrameResidual& r = d.residual;
      summary << "  residual structure (" << r.finding << ", p " << r.p_value << ")"
              << (chain.empty() ? "" : " after " + chain) << ": positions rms " << r.position_rms_arcsec
              << " arcsec, largest " << r.position_max_arcsec << " arcsec at (" << r.position_max_x_px << ", "
              << r.position_max_y_px << ") px; fluxes rms " << r.photometry_rms_mag << " mag, largest "
              << r.photometry_max_mag << " mag at (" << r.photometry_max_x_px << ", " << r.photometry_max_y_px
              << ") px\n";
    }
    ssiu::Json j = ssiu::FrameDiscoveryToJson(d);
    j["frame_status"] = ssiu::Json::object();
    for (size_t i = 0; i < set.status.size(); ++i) j["frame_status"][o->frames[i]] = SolveStatusName(set.status[i]);
    if (!o->json.empty()) ssiu::WriteJsonFile(o->json, j);
    if (!o->plot.empty()) ssiu::WriteResidualQuiver(o->plot, d, cam);
    if (!o->compare_sim.empty()) {
      // The model under test, then the extended one: the fitted camera (frames re-solved with it)
      // and the simulator options fitted to the measured figures, at the frames' bit depth.
      ssiu::FrameCompareOptions co;
      if (!o->sim_json.empty()) co.sim = ssiu::FrameSimOptionsFromJson(ssiu::ReadJsonFile(o->sim_json), o->sim_json);
      const ssiu::StarCatalog sky = ssiu::SkyForCamera(cam, o->fov_tolerance_pct, co.sim.mag_max);
      const ssiu::FrameComparison before = ssiu::CompareWithSimulation(set, views, cam, sky, id, so, co);
      ssiu::FrameCompareOptions co2 = co;
      co2.sim = ssiu::FitSimOptions(before.measured, co.sim);
      co2.sim.bit_depth = frames.front().bit_depth;
      const ssiu::Camera cam2 = d.fitted_camera;
      const ssiu::SolvedFrameSet set2 =
          ssiu::SolveFrameSet(id, views, o->frames, cam2, so, known.empty() ? nullptr : &known);
      const ssiu::FrameComparison after = ssiu::CompareWithSimulation(set2, views, cam2, sky, id, so, co2);
      ssiu::Json cj;
      cj["model"] = {{"camera", ssiu::CameraToJson(cam)}, {"sim_options", ssiu::FrameSimOptionsToJson(co.sim)}};
      cj["before"] = ssiu::FrameComparisonToJson(before);
      cj["extended_model"] = {{"camera", ssiu::CameraToJson(cam2)},
                              {"sim_options_changed", ssiu::FrameSimOptionsDiff(co.sim, co2.sim)}};
      cj["after"] = ssiu::FrameComparisonToJson(after);
      summary << "compare-sim: position rms " << before.position_rms_px << " -> " << after.position_rms_px
              << " px; flux ratio " << before.flux_ratio_median << " -> " << after.flux_ratio_median
              << "; spot sigma measured " << before.measured.psf_sigma_px << " vs simulated "
              << before.simulated.psf_sigma_px << " -> " << after.simulated.psf_sigma_px << " px; noise measured "
              << before.measured.noise_adu << " vs simulated " << before.simulated.noise_adu << " -> "
              << after.simulated.noise_adu << " ADU\n";
      ssiu::WriteJsonFile(o->compare_sim, cj);
      if (!o->plot.empty()) {
        ssiu::WriteComparePlots(o->plot, "compare_before", before, cam, "simulator defaults");
        ssiu::WriteComparePlots(o->plot, "compare_after", after, cam2, "extended model");
      }
    }
    if (!o->defects_out.empty()) {
      ssiu::DefectMap map = known;
      for (const auto& h : d.hot_pixels) ssiu::MarkHotPixel(h.x, h.y, cam.width, cam.height, &map);
      ssiu::SaveDefectMap(o->defects_out, map);
    }
    std::cerr << summary.str();
  });
});

SSIU_REGISTER_COMMAND(discover_gyro, [](CLI::App& root) {
  auto* discover = ssiu::cli::GetOrAddSubcommand(root, "discover", "Find what the model gets wrong in measured data");
  auto* cmd = discover->add_subcommand(
      "gyro",
      "Test candidate causes (temperature, magnetic_field, scale_factor, bias_step, periodic_drift, ...) against the "
      "base gyro model; a cause is named only when its held-out gain is significant and its parameters are within "
      "physical bounds; `unexplained` when the residual keeps structure (spectral peak, autocorrelation, runs, a "
      "logged column, jumps between two levels, a periodic drift that is not a sinusoid, a change of the noise "
      "level, outliers, a nonlinear function of the reference rate or the azimuth's second harmonic, a trend or a "
      "warm-up in time, a spectral line above the bins' band in the raw samples) that no cause "
      "explains; the JSON's `residual` block gives each test's statistic and p-value. The model is extended step by "
      "step: each named cause joins the base model and the rest are tested again until none passes (`causes`: the "
      "chain with the joint fit's parameters; `cause` is the first) (docs/discrepancy.md)");
  auto o = std::make_shared<GyroOpts>();
  cmd->add_option("logs", o->logs,
                  "Bench logs t_s,w_dph,ref_dph,temp_c[,azimuth_deg][,bn_ut,be_ut,bh_ut] (other numeric columns "
                  "are kept for the residual test)")
      ->required();
  cmd->add_option("--json", o->json, "Output JSON, - for stdout");
  cmd->add_option("--alpha", o->opt.alpha, "Family-wise false-alarm probability")->capture_default_str();
  cmd->add_option("--max-bins", o->opt.max_bins_per_log, "Bins per log at most")->capture_default_str();
  cmd->add_option("--wander-tau-max-s", o->opt.wander_tau_max_s, "Longest correlation time of the base wander, s")
      ->capture_default_str();
  cmd->add_option("--cv-blocks", o->opt.cv_blocks, "Blocks per log for the cross-validated gain")
      ->capture_default_str();
  cmd->add_option("--gain-alpha", o->opt.gain_alpha,
                  "One-sided false-alarm probability of the held-out gain's significance gate")
      ->capture_default_str();
  cmd->add_option("--min-block-z", o->opt.min_block_z,
                  "The held-out improvement judged by the held-out blocks' own scatter must exceed this many "
                  "standard errors (consistency check of the modelled gain z)")
      ->capture_default_str();
  cmd->add_option("--min-temp-span-c", o->opt.min_temp_span_c, "Temperature terms tested only when T moves this much")
      ->capture_default_str();
  cmd->add_option("--rrw-min-log-s", o->opt.rrw_min_log_s, "Random walk tested only on logs this long")
      ->capture_default_str();
  cmd->add_option("--residual-alpha", o->opt.residual_alpha,
                  "False-alarm probability of the residual tests behind `unexplained`")
      ->capture_default_str();
  cmd->callback([o] {
    std::vector<ssiu::GyroBenchLog> logs;
    for (const auto& f : o->logs) logs.push_back(ssiu::ReadGyroBenchLog(f));
    const ssiu::GyroDiscovery d = ssiu::DiscoverGyro(logs, o->opt);
    // Output first: a path that cannot be written is then the only line printed.
    if (!o->json.empty()) ssiu::WriteJsonFile(o->json, ssiu::GyroDiscoveryToJson(d));
    // The chain of named causes (the stepwise extension), each with its joint-fit parameters.
    std::string chain;
    for (const auto& c : d.causes) chain += (chain.empty() ? "" : " + ") + c.cause;
    std::cerr << "discover gyro: cause " << (d.cause == "unexplained" || chain.empty() ? d.cause : chain);
    const bool several = d.causes.size() > 1;
    for (const auto& c : d.causes) {
      if (several) std::cerr << (&c == &d.causes.front() ? " (" : "; ") << c.cause << ":";
      for (const auto& [k, v] : c.parameters) std::cerr << " " << k << "=" << v << "+-" << c.sigmas.at(k);
    }
    if (several) std::cerr << ")";
    std::cerr << "; held-out rms " << d.rms_before_dph << " -> " << d.rms_after_dph << " deg/h (gain " << d.gain
              << (d.causes.size() > 1 ? ", first cause" : "") << ")\n";
    // The ties the data do not break: a rival fits about as well in a named cause's place.
    for (const auto& c : d.causes) {
      if (c.rivals.empty()) continue;
      std::cerr << "  in place of " << c.cause << " the data support about as well:";
      for (const auto& r : c.rivals)
        std::cerr << " " << r.cause << " (BIC " << std::showpos << r.delta_bic << std::noshowpos << ")";
      std::cerr << "\n";
    }
    if (d.cause == "unexplained") {
      std::cerr << "  residual structure (" << d.residual.finding << ", p " << d.residual.p_value << "): period "
                << d.residual.period_s << " s, amplitude " << d.residual.amplitude_dph << " deg/h, follows column "
                << d.residual.follows_column << " (" << d.residual.column_coefficient << " deg/h per unit)";
      if (d.residual.finding == "variance_change") {
        std::cerr << "; noise level changes at " << d.residual.variance_change_time_s << " s (variance x"
                  << d.residual.variance_ratio << ")";
      } else if (d.residual.finding == "outliers") {
        std::cerr << "; " << d.residual.outliers << " outliers (largest " << d.residual.outlier_max_sigma << " sigma)";
      } else if (d.residual.finding == "nonlinearity") {
        std::cerr << "; follows " << d.residual.nonlinear_term << " of the reference";
      } else if (d.residual.finding == "spectral_line") {
        std::cerr << "; a line at " << d.residual.line_frequency_hz << " Hz, amplitude "
                  << d.residual.line_amplitude_dph << " deg/h (above the bins' band)";
      } else if (d.residual.finding == "trend") {
        std::cerr << "; a shape in time: " << d.residual.trend_term;
        if (d.residual.trend_term == "exp(-t/tau)") std::cerr << " with tau " << d.residual.warm_up_tau_s << " s";
      }
      if (!d.partial_cause.empty()) std::cerr << "; fitted first: " << chain;
      std::cerr << "\n";
    }
  });
});
