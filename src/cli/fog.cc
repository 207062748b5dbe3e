// `ssiu fog thermal|compensate|magnetic`: the FOG bench calibration (docs/fog-calibration.md).
#include <cmath>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <sstream>

#include "calibration/fog_magnetic.h"
#include "calibration/fog_plot.h"
#include "calibration/fog_thermal.h"
#include "cli/command.h"
#include "core/csv.h"
#include "core/error.h"
#include "core/json.h"
#include "core/types.h"

namespace {

void MakeDir(const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw ssiu::InputError(dir, "cannot create plot directory");
}

void PlotThermal(const std::string& dir, const ssiu::ThermalEvaluation& ev, const std::string& tag) {
  MakeDir(dir);
  ssiu::FogPlot drift{"Drift error without and with compensation (" + tag + ")", "time, min", "drift, deg/h", {}};
  ssiu::FogPlot angle{
      "Accumulated angle error without and with compensation (" + tag + ")", "time, min", "angle, deg", {}};
  double offset = 0;
  for (size_t r = 0; r < ev.runs.size(); ++r) {
    const auto& s = ev.runs[r];
    std::vector<double> t;
    for (double v : s.t_min) t.push_back(v + offset);
    const std::string name = "run " + std::to_string(r + 1);
    drift.series.push_back({name + " uncompensated", t, s.drift_before_dph, false});
    drift.series.push_back({name + " compensated", t, s.drift_after_dph, false});
    angle.series.push_back({name + " uncompensated", t, s.angle_before_deg, false});
    angle.series.push_back({name + " compensated", t, s.angle_after_deg, false});
    if (!t.empty()) offset = t.back() + 1;
  }
  ssiu::WriteFogPlotPng(dir + "/" + tag + "_drift.png", drift);
  ssiu::WriteFogPlotPng(dir + "/" + tag + "_angle.png", angle);
}

struct ThermalOpts {
  std::vector<std::string> runs;
  std::vector<std::string> holdout;
  std::string json, plot, axis = "up";
  double latitude_deg = std::numeric_limits<double>::quiet_NaN();
  ssiu::ThermalFitOptions fit;
};

struct CompensateOpts {
  std::string log, model, out, json, axis = "up";
  double latitude_deg = std::numeric_limits<double>::quiet_NaN();
};

struct MagneticOpts {
  std::vector<std::string> logs;
  std::string json, plot;
  ssiu::MagneticOptions fit;
};

}  // namespace

SSIU_REGISTER_COMMAND(fog_thermal, [](CLI::App& root) {
  auto* fog = ssiu::cli::GetOrAddSubcommand(root, "fog", "FOG bench calibration (thermal drift, magnetic sensitivity)");
  auto* cmd = fog->add_subcommand("thermal", "Fit the temperature-drift model (SSIU eq. 1) with term selection");
  auto o = std::make_shared<ThermalOpts>();
  cmd->add_option("runs", o->runs, "Run CSVs t_s,w_dph,ref_dph,temp_c (fitted together)")->required();
  cmd->add_option("--holdout", o->holdout, "Run CSVs not fitted, used to measure the compensation gain");
  cmd->add_option("--json", o->json, "Output JSON (the model for `fog compensate`), - for stdout");
  cmd->add_option("--plot", o->plot, "Directory for the PNG figures");
  cmd->add_option("--latitude-deg", o->latitude_deg, "Bench latitude, when the logs have no ref_dph");
  cmd->add_option("--axis", o->axis, "Sensing axis on the bench without ref_dph: up, down, north, south, east, west");
  cmd->add_option("--bin-s", o->fit.bin_s, "Averaging bin, s")->capture_default_str();
  cmd->add_option("--rate-window-s", o->fit.rate.window_s, "Window of the local cubic fit for T and dT/dt, s")
      ->capture_default_str();
  cmd->add_flag("!--no-prewhiten", o->fit.prewhiten, "Do not prewhiten (for comparison)");
  cmd->add_flag("!--no-neff", o->fit.effective_sample_size, "Do not shrink the sample size (for comparison)");
  cmd->callback([o] {
    std::vector<ssiu::ThermalRun> runs, held;
    for (const auto& p : o->runs) runs.push_back(ssiu::ReadThermalRun(p, o->latitude_deg, o->axis));
    for (const auto& p : o->holdout) held.push_back(ssiu::ReadThermalRun(p, o->latitude_deg, o->axis));
    const ssiu::ThermalFitResult fit = ssiu::FitThermalDrift(runs, o->fit);
    ssiu::Json j = ssiu::ThermalFitToJson(fit, o->fit);
    // The summary is printed after the outputs are written, so that an output path that cannot be
    // written gives the one error line only.
    std::ostringstream summary;
    summary << "fog thermal: kept";
    for (const auto& t : fit.tested) {
      if (t.kept) summary << " " << t.name << "=" << t.estimate_dph << "+-" << t.sigma_dph;
    }
    summary << "; fitted runs: band " << fit.evaluation.before.peak_dph << " -> " << fit.evaluation.after.peak_dph
            << " deg/h (gain " << fit.evaluation.gain << ")\n";
    if (!held.empty()) {
      const ssiu::ThermalEvaluation hev = ssiu::EvaluateThermalModel(held, fit.model, o->fit);
      j["holdout"] = ssiu::ThermalEvaluationToJson(hev);
      summary << "fog thermal: held-out runs: band " << hev.before.peak_dph << " -> " << hev.after.peak_dph
              << " deg/h (gain " << hev.gain << "), angle " << hev.angle_error_before_deg << " -> "
              << hev.angle_error_after_deg << " deg\n";
      if (!o->plot.empty()) PlotThermal(o->plot, hev, "holdout");
    }
    if (!o->plot.empty()) PlotThermal(o->plot, fit.evaluation, "fitted");
    if (!o->json.empty()) ssiu::WriteJsonFile(o->json, j);
    std::cerr << summary.str();
  });
});

SSIU_REGISTER_COMMAND(fog_compensate, [](CLI::App& root) {
  auto* fog = ssiu::cli::GetOrAddSubcommand(root, "fog", "FOG bench calibration (thermal drift, magnetic sensitivity)");
  auto* cmd = fog->add_subcommand("compensate", "Apply a fitted temperature-drift model to a log");
  auto o = std::make_shared<CompensateOpts>();
  cmd->add_option("log", o->log, "Log CSV t_s,w_dph,temp_c[,ref_dph]")->required();
  cmd->add_option("--model", o->model, "Model JSON written by `fog thermal --json`")->required();
  cmd->add_option("--out", o->out, "Output CSV t_s,w_dph,w_comp_dph,model_dph,temp_c,rate_c_per_min")->required();
  cmd->add_option("--json", o->json, "Summary JSON (drift band before/after), - for stdout");
  cmd->add_option("--latitude-deg", o->latitude_deg, "Bench latitude, when the log has no ref_dph");
  cmd->add_option("--axis", o->axis, "Sensing axis on the bench without ref_dph");
  cmd->callback([o] {
    const ssiu::ThermalModelFile m = ssiu::ThermalModelFromJson(ssiu::ReadJsonFile(o->model), o->model);
    // The reference is only needed for the summary; a log without it is compensated all the same.
    const ssiu::CsvTable probe = ssiu::ReadCsv(o->log);
    const bool has_ref = probe.Has("ref_dph") || std::isfinite(o->latitude_deg);
    const ssiu::ThermalRun run =
        ssiu::ReadThermalRun(o->log, has_ref ? o->latitude_deg : 0.0, has_ref ? o->axis : "east");
    const ssiu::ThermalCompensation c = ssiu::CompensateThermalRun(run, m.model, m.rate);
    ssiu::WriteCsv(o->out, {"t_s", "w_dph", "w_comp_dph", "model_dph", "temp_c", "rate_c_per_min"},
                   {c.t_s, c.w_dph, c.w_comp_dph, c.model_dph, c.temp_c, c.rate_c_per_min});
    if (has_ref) {
      ssiu::ThermalFitOptions fo;
      fo.bin_s = m.bin_s;
      fo.rate = m.rate;
      const ssiu::ThermalEvaluation ev = ssiu::EvaluateThermalModel({run}, m.model, fo);
      std::cerr << "fog compensate: band " << ev.before.peak_dph << " -> " << ev.after.peak_dph << " deg/h (gain "
                << ev.gain << ")\n";
      if (!o->json.empty()) ssiu::WriteJsonFile(o->json, ssiu::ThermalEvaluationToJson(ev));
    }
  });
});

SSIU_REGISTER_COMMAND(fog_magnetic, [](CLI::App& root) {
  auto* fog = ssiu::cli::GetOrAddSubcommand(root, "fog", "FOG bench calibration (thermal drift, magnetic sensitivity)");
  auto* cmd = fog->add_subcommand("magnetic", "Turntable test: trim error and magnetic sensitivity (SSIU eqs. 2-4)");
  auto o = std::make_shared<MagneticOpts>();
  cmd->add_option("logs", o->logs,
                  "One or two turntable CSVs t_s,wx_dph,wy_dph,azimuth_deg (e.g. before/after shielding)")
      ->required()
      ->expected(1, 2);
  cmd->add_option("--latitude-deg", o->fit.latitude_deg, "Bench latitude")->capture_default_str();
  cmd->add_option("--settle-s", o->fit.settle_s, "Transient excluded after each turn, s")->capture_default_str();
  cmd->add_option("--min-positions", o->fit.min_positions, "Distinct azimuths required")->capture_default_str();
  cmd->add_option("--wander-dph", o->fit.wander_sigma_dph, "FOG bias wander sigma (Gauss-Markov), deg/h; 0 = none")
      ->capture_default_str();
  cmd->add_option("--wander-tau-s", o->fit.wander_tau_s, "Correlation time of the bias wander, s")
      ->capture_default_str();
  cmd->add_option("--json", o->json, "Output JSON, - for stdout");
  cmd->add_option("--plot", o->plot, "Directory for the PNG figures");
  cmd->callback([o] {
    std::vector<ssiu::MagneticResult> fits;
    for (const auto& p : o->logs) fits.push_back(ssiu::FitMagneticSensitivity(ssiu::ReadTurntableLog(p), o->fit));
    ssiu::Json j = ssiu::MagneticResultToJson(fits[0]);
    std::ostringstream summary;  // printed after the outputs, as in `fog thermal`
    for (const auto& f : fits) {
      summary << "fog magnetic: " << f.file << ": dpsi0 " << f.dpsi0_deg << "+-" << f.dpsi0_sigma_deg
              << " deg, magnetic amplitude " << f.magnetic_amplitude_dph << "+-" << f.magnetic_amplitude_sigma_dph
              << " deg/h, chi2 " << f.magnetic_chi2 << (f.consistent_with_zero ? " (consistent with zero)" : "")
              << "\n";
    }
    std::vector<ssiu::MagneticCurves> curves;
    for (const auto& f : fits) curves.push_back(ssiu::MagneticFitCurves(f));
    if (fits.size() == 2) {
      j["second"] = ssiu::MagneticResultToJson(fits[1]);
      double dx = 0, dy = 0;
      for (size_t i = 0; i < curves[0].psi_deg.size(); ++i) {
        dx = std::max(dx, std::abs(curves[1].mag_x_dph[i] - curves[0].mag_x_dph[i]));
        dy = std::max(dy, std::abs(curves[1].mag_y_dph[i] - curves[0].mag_y_dph[i]));
      }
      j["difference"] = {
          {"magnetic_x_peak_dph", dx},
          {"magnetic_y_peak_dph", dy},
          {"magnetic_amplitude_change_dph", fits[1].magnetic_amplitude_dph - fits[0].magnetic_amplitude_dph}};
    }
    if (!o->plot.empty()) {
      MakeDir(o->plot);
      ssiu::FogPlot fp{"Error functions f_x, f_y: dwell means and fits", "azimuth, deg", "deg/h", {}};
      ssiu::FogPlot mp{"Magnetic error (trim removed)", "azimuth, deg", "deg/h", {}};
      for (size_t k = 0; k < fits.size(); ++k) {
        const std::string tag = fits.size() == 2 ? (k == 0 ? "log 1 " : "log 2 ") : "";
        std::vector<double> az, fx, fy;
        for (const auto& d : fits[k].dwells) {
          az.push_back(d.azimuth_deg);
          fx.push_back(d.wx_dph - fits[k].w_phi_dph * std::cos(d.azimuth_deg * ssiu::kDegToRad));
          fy.push_back(d.wy_dph - fits[k].w_phi_dph * std::sin(d.azimuth_deg * ssiu::kDegToRad));
        }
        fp.series.push_back({tag + "f_x fit", curves[k].psi_deg, curves[k].fx_dph, false});
        fp.series.push_back({tag + "f_x dwells", az, fx, true});
        fp.series.push_back({tag + "f_y fit", curves[k].psi_deg, curves[k].fy_dph, false});
        fp.series.push_back({tag + "f_y dwells", az, fy, true});
        mp.series.push_back({tag + "magnetic x", curves[k].psi_deg, curves[k].mag_x_dph, false});
        mp.series.push_back({tag + "magnetic y", curves[k].psi_deg, curves[k].mag_y_dph, false});
      }
      if (fits.size() == 2) {
        std::vector<double> ddx, ddy;
        for (size_t i = 0; i < curves[0].psi_deg.size(); ++i) {
          ddx.push_back(curves[1].mag_x_dph[i] - curves[0].mag_x_dph[i]);
          ddy.push_back(curves[1].mag_y_dph[i] - curves[0].mag_y_dph[i]);
        }
        ssiu::FogPlot dp{"Difference of the magnetic error, log 2 - log 1", "azimuth, deg", "deg/h", {}};
        dp.series.push_back({"x", curves[0].psi_deg, ddx, false});
        dp.series.push_back({"y", curves[0].psi_deg, ddy, false});
        ssiu::WriteFogPlotPng(o->plot + "/magnetic_difference.png", dp);
      }
      ssiu::WriteFogPlotPng(o->plot + "/magnetic_fit.png", fp);
      ssiu::WriteFogPlotPng(o->plot + "/magnetic_error.png", mp);
    }
    if (!o->json.empty()) ssiu::WriteJsonFile(o->json, j);
    std::cerr << summary.str();
  });
});
