// `ssiu allan LOG.csv --column NAME --json OUT [--plot OUT.png]`: overlapping Allan deviation of one
// rate column with confidence intervals and the fitted IEEE 952 noise terms; or, with --curve, the
// same fit on an Allan curve computed elsewhere (e.g. ../shared/data/gyro/).
#include "calibration/allan.h"

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "calibration/allan_io.h"
#include "cli/command.h"
#include "core/error.h"
#include "core/json.h"

namespace {

struct Opts {
  std::string log, column, curve, json, plot;
  std::string unit, tau_column, adev_column, channel, tau_file;
  double sample_rate_hz = 0, duration_s = 0, n = 0;
  double confidence = 0.683;
  int points_per_decade = 10;
  double tau_min_s = 0, tau_max_s = 0;
  double model_error = 0.02;
  bool no_quantization = false, no_rate_ramp = false, no_bias_instability = false;
};

void PrintTerm(const char* name, const ssiu::NoiseTerm& t, const char* unit) {
  if (t.value <= 0) {
    std::fprintf(stderr, "  %-22s not fitted\n", name);
    return;
  }
  std::fprintf(stderr, "  %-22s %.4g +- %.2g %s", name, t.value, t.sigma, unit);
  if (t.tau_max_s > 0) std::fprintf(stderr, "  (tau %.3g..%.3g s)", t.tau_min_s, t.tau_max_s);
  std::fprintf(stderr, "%s\n", t.significant ? "" : "  [not significant]");
}

// A flag that is given must make sense: a negative or non-finite value used to be ignored (a log's
// t_s used instead of --sample-rate-hz) or to stop the fit with an internal error.
void CheckNonNegative(double v, const char* flag) {
  if (!std::isfinite(v) || v < 0) throw ssiu::InputError(flag, "must be a finite number >= 0");
}

void Run(const Opts& o) {
  if (o.log.empty() == o.curve.empty())
    throw ssiu::InputError("", "give either a LOG.csv with --column, or --curve FILE");
  CheckNonNegative(o.sample_rate_hz, "--sample-rate-hz");
  CheckNonNegative(o.duration_s, "--duration-s");
  CheckNonNegative(o.n, "--n");
  CheckNonNegative(o.tau_min_s, "--tau-min-s");
  CheckNonNegative(o.tau_max_s, "--tau-max-s");
  if (!(o.confidence > 0 && o.confidence < 1)) throw ssiu::InputError("--confidence", "must be in (0, 1)");
  ssiu::AllanCurve curve;
  ssiu::Json provenance;
  std::string title;
  if (!o.log.empty()) {
    if (o.column.empty()) throw ssiu::InputError(o.log, "--column NAME is required with a log");
    const ssiu::RateLog log = ssiu::ReadRateLog(o.log, o.column, o.unit, o.sample_rate_hz);
    ssiu::AllanOptions ao;
    ao.points_per_decade = o.points_per_decade;
    ao.confidence = o.confidence;
    if (log.rate_rad_s.size() < ao.min_samples) {
      throw ssiu::InputError(o.log, "column '" + o.column + "': too few samples (" +
                                        std::to_string(log.rate_rad_s.size()) + ", need " +
                                        std::to_string(ao.min_samples) + ")");
    }
    curve = ssiu::OverlappingAllanDeviation(log.rate_rad_s, log.sample_rate_hz, ao);
    provenance = {
        {"file", o.log}, {"column", o.column}, {"source", "log"}, {"rate_unit", ssiu::RateUnitName(log.unit)}};
    title = o.log + " : " + o.column;
  } else {
    ssiu::CurveFileOptions co;
    co.tau_column = o.tau_column;
    co.adev_column = o.adev_column;
    co.channel = o.channel;
    co.tau_file = o.tau_file;
    co.unit = o.unit;
    co.sample_rate_hz = o.sample_rate_hz;
    co.duration_s = o.duration_s;
    co.n = o.n;
    co.confidence = o.confidence;
    const ssiu::CurveFile cf = ssiu::ReadAllanCurveFile(o.curve, co);
    curve = cf.curve;
    provenance = {{"file", o.curve},
                  {"column", cf.adev_column},
                  {"channel", cf.channel},
                  {"source", "curve"},
                  {"rate_unit", ssiu::RateUnitName(cf.unit)},
                  {"tau_column", cf.tau_column}};
    title = o.curve + (cf.channel.empty() ? "" : " : " + cf.channel);
  }
  ssiu::NoiseFitOptions fo;
  fo.tau_min_s = o.tau_min_s;
  fo.tau_max_s = o.tau_max_s;
  fo.model_error = o.model_error;
  fo.fit_quantization = !o.no_quantization;
  fo.fit_rate_ramp = !o.no_rate_ramp;
  fo.fit_bias_instability = !o.no_bias_instability;
  if (!(fo.model_error >= 0 && fo.model_error < 1)) throw ssiu::InputError("--model-error", "must be in [0, 1)");
  if (fo.tau_max_s > 0 && fo.tau_max_s <= fo.tau_min_s)
    throw ssiu::InputError("--tau-max-s", "must exceed --tau-min-s");
  const ssiu::NoiseFit fit = ssiu::FitNoiseTerms(curve, fo);
  if (!o.json.empty()) ssiu::WriteJsonFile(o.json, ssiu::AllanReportJson(curve, fit, provenance, o.confidence));
  if (!o.plot.empty()) ssiu::WriteAllanPlot(o.plot, curve, fit, title);
  // Human summary on stderr (stdout may carry the JSON).
  std::fprintf(stderr, "%s: %zu Allan points, tau %.3g..%.3g s, edf from %s; fit %s\n", title.c_str(),
               curve.tau_s.size(), curve.tau_s.empty() ? 0.0 : curve.tau_s.front(),
               curve.tau_s.empty() ? 0.0 : curve.tau_s.back(), curve.edf_source.c_str(),
               ssiu::FitStatusName(fit.status));
  if (fit.status != ssiu::FitStatus::kFitted) {
    std::fprintf(stderr, "  %s\n", fit.message.c_str());
    return;
  }
  const ssiu::GyroNoiseTerms g = ssiu::ToGyroUnits(fit);
  PrintTerm("quantization", g.quantization_arcsec, "arcsec");
  PrintTerm("angle random walk", g.arw_deg_per_sqrt_h, "deg/sqrt(h)");
  PrintTerm("bias instability", g.bias_instability_dph, "deg/h");
  PrintTerm(fit.adev_min_is_upper_bound ? "bias instab. floor <=" : "bias instab. (floor)",
            g.bias_instability_floor_dph, "deg/h");
  PrintTerm("rate random walk", g.rrw_deg_per_h_per_sqrt_h, "deg/h/sqrt(h)");
  PrintTerm("rate ramp", g.rate_ramp_deg_per_h2, "deg/h^2");
}

}  // namespace

SSIU_REGISTER_COMMAND(allan, [](CLI::App& root) {
  auto* cmd = root.add_subcommand(
      "allan",
      "Overlapping Allan deviation with confidence intervals and fitted gyro noise terms (IEEE Std 952): "
      "angle random walk, bias instability, rate random walk, quantisation, rate ramp");
  auto o = std::make_shared<Opts>();
  cmd->add_option("log", o->log, "Gyro log CSV with t_s and a rate column");
  cmd->add_option("--column", o->column, "Rate column of the log (unit from its name: _dph, _dps, _rps)");
  cmd->add_option("--curve", o->curve,
                  "Fit an Allan curve computed elsewhere instead of a log (CSV, or one-column ADEV with --tau-file)");
  cmd->add_option("--json", o->json, "Output JSON file, - for stdout");
  cmd->add_option("--plot", o->plot, "Output PNG of the curve and the fitted terms");
  cmd->add_option("--unit", o->unit, "Rate unit when not in the column name: rad/s, deg/s or deg/h");
  cmd->add_option("--tau-column", o->tau_column, "Curve: tau column (default: tau_s, tau, ...)");
  cmd->add_option("--adev-column", o->adev_column, "Curve: ADEV column (default: adev*, else avar*, square-rooted)");
  cmd->add_option("--channel", o->channel, "Curve: rows of this channel (e.g. \"Gyro. X\")");
  cmd->add_option("--tau-file", o->tau_file, "Curve: taus in a separate one-column file (imu_utils)");
  cmd->add_option("--sample-rate-hz", o->sample_rate_hz, "Log: instead of t_s; curve: rate behind the curve (for edf)");
  cmd->add_option("--duration-s", o->duration_s, "Curve: length of the log behind the curve (for edf)");
  cmd->add_option("--n", o->n, "Curve: number of samples behind the curve (for edf)");
  cmd->add_option("--confidence", o->confidence, "Two-sided confidence level of adev_lo..adev_hi (default 0.683)");
  cmd->add_option("--points-per-decade", o->points_per_decade, "Tau grid density (default 10)");
  cmd->add_option("--tau-min-s", o->tau_min_s, "Fit only taus >= this");
  cmd->add_option("--tau-max-s", o->tau_max_s, "Fit only taus <= this");
  cmd->add_option("--model-error", o->model_error, "Relative ADEV error floor in the fit weights (default 0.02)");
  cmd->add_flag("--no-quantization", o->no_quantization, "Leave the quantisation term out of the fit");
  cmd->add_flag("--no-bias-instability", o->no_bias_instability, "Leave the bias-instability term out of the fit");
  cmd->add_flag("--no-rate-ramp", o->no_rate_ramp, "Leave the rate-ramp term out of the fit");
  cmd->callback([o] {
    if (o->points_per_decade < 1 || o->points_per_decade > 1000) {
      throw ssiu::InputError("--points-per-decade", "must be in 1..1000");
    }
    Run(*o);
  });
});
