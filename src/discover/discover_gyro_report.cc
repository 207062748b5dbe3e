// The JSON report of `ssiu discover gyro`.
#include <vector>

#include "discover/discover_gyro.h"
#include "discover/discovery_json.h"

namespace ssiu {

namespace {

// The candidates of one step: each one's test, and the gates' figures when it was evaluated.
Json CandidatesJson(const std::vector<GyroCandidate>& candidates) {
  Json out = Json::array();
  for (const auto& c : candidates) {
    Json cj = {{"cause", c.cause}, {"applicable", c.applicable}};
    if (!c.model.empty()) cj["model"] = c.model;
    if (c.applicable) {
      cj["statistic"] = c.statistic;
      cj["p_value"] = c.p_value;
      cj["delta_bic"] = c.delta_bic;
      cj["significant"] = c.significant;
      if (c.significant) cj["likelihood_bic"] = c.bic;
      if (c.evaluated) {
        cj["gain"] = c.gain;
        cj["gain_z"] = c.gain_z;
        cj["gain_z_blocks"] = c.gain_z_blocks;
        cj["verdict"] = c.verdict;
      }
    }
    out.push_back(cj);
  }
  return out;
}

}  // namespace

Json GyroDiscoveryToJson(const GyroDiscovery& d) {
  Json j = discover_internal::DiscoveryVerdictJson(d.cause, d.parameters, d.sigmas, d.gain, d.gain_z, d.gain_z_min,
                                                   d.partial_cause);
  j["rms_before_dph"] = d.rms_before_dph;
  j["rms_after_dph"] = d.rms_after_dph;
  j["gain_method"] = d.cause == "rate_random_walk" ? "held-out one-step prediction (second half of each log)"
                                                   : "cross-validation on interleaved blocks";
  j["evidence"] = {{"n_bins", d.n_bins},
                   {"n_eff", d.n_eff},
                   {"variance_inflation", d.variance_inflation},
                   {"noise_white_dph", d.noise_white_dph},
                   {"noise_wander_dph", d.noise_wander_dph},
                   {"noise_wander_tau_s", d.noise_wander_tau_s},
                   {"alpha_per_candidate", d.alpha_per_candidate}};
  {
    const GyroResidual& r = d.residual;
    Json rj = discover_internal::ResidualVerdictJson(r.structured, r.p_value, r.finding);
    rj.update(Json{{"rms_dph", r.rms_dph},
                   {"period_s", r.period_s},
                   {"amplitude_dph", r.amplitude_dph},
                   {"spectral_chi2", r.spectral_chi2},
                   {"spectral_p", r.spectral_p},
                   {"ljung_box_q", r.ljung_box_q},
                   {"ljung_box_lags", r.ljung_box_lags},
                   {"ljung_box_p", r.ljung_box_p},
                   {"runs_z", r.runs_z},
                   {"runs_p", r.runs_p},
                   {"follows_column", r.follows_column},
                   {"column_coefficient_dph_per_unit", r.column_coefficient},
                   {"column_correlation", r.column_correlation},
                   {"column_p", r.column_p},
                   {"harmonics_p", r.harmonics_p},
                   {"harmonic_period_s", r.harmonic_period_s},
                   {"periodic_shape_chi2", r.periodic_shape_chi2},
                   {"periodic_shape_dof", r.periodic_shape_dof},
                   {"periodic_shape_p", r.periodic_shape_p},
                   {"jumps", r.jumps},
                   {"levels_within_ratio", r.levels_within_ratio},
                   {"jumps_p", r.jumps_p},
                   {"levels_within_p", r.levels_within_p},
                   {"telegraph_llr", r.telegraph_llr},
                   {"telegraph_p", r.telegraph_p},
                   {"telegraph_share", r.telegraph_share},
                   {"telegraph_levels_dph", r.telegraph_levels_dph},
                   {"telegraph_dwell_s", r.telegraph_dwell_s},
                   {"jump_size_dph", r.jump_size_dph},
                   {"jump_times_s", r.jump_times_s},
                   {"variance_change_stat", r.variance_change_stat},
                   {"variance_change_p", r.variance_change_p},
                   {"variance_change_time_s", r.variance_change_time_s},
                   {"variance_ratio", r.variance_ratio},
                   {"outliers", r.outliers},
                   {"outlier_times_s", r.outlier_times_s},
                   {"outlier_max_sigma", r.outlier_max_sigma},
                   {"outliers_p", r.outliers_p},
                   {"nonlinear_chi2", r.nonlinear_chi2},
                   {"nonlinear_dof", r.nonlinear_dof},
                   {"nonlinear_p", r.nonlinear_p},
                   {"nonlinear_term", r.nonlinear_term},
                   {"trend_chi2", r.trend_chi2},
                   {"trend_dof", r.trend_dof},
                   {"trend_p", r.trend_p},
                   {"trend_term", r.trend_term},
                   {"line_p", r.line_p},
                   {"line_frequency_hz", r.line_frequency_hz},
                   {"line_amplitude_dph", r.line_amplitude_dph},
                   {"line_power_ratio", r.line_power_ratio},
                   {"warm_up_tau_s", r.warm_up_tau_s}});
    rj["trend_coefficients_dph"] = Json::object();
    for (const auto& [k, v] : r.trend_coefficients_dph) rj["trend_coefficients_dph"][k] = v;
    rj["nonlinear_coefficients_dph"] = Json::object();
    for (const auto& [k, v] : r.nonlinear_coefficients_dph) rj["nonlinear_coefficients_dph"][k] = v;
    rj["columns"] = Json::array();
    for (const auto& c : r.columns) {
      rj["columns"].push_back({{"column", c.column},
                               {"chi2", c.chi2},
                               {"p_value", c.p_value},
                               {"coefficient_dph_per_unit", c.coefficient_dph_per_unit},
                               {"correlation", c.correlation}});
    }
    j["residual"] = rj;
  }
  j["candidates"] = CandidatesJson(d.candidates);
  // The stepwise extension: the chain in the order the causes entered, with the joint fit's parameters.
  j["causes"] = Json::array();
  for (const auto& c : d.causes) {
    Json cj = {{"cause", c.cause}};
    if (!c.model.empty()) cj["model"] = c.model;
    cj["parameters"] = Json::object();
    for (const auto& [k, v] : c.parameters) cj["parameters"][k] = v;
    cj["parameter_sigmas"] = Json::object();
    for (const auto& [k, v] : c.sigmas) cj["parameter_sigmas"][k] = v;
    cj["gain"] = c.gain;
    cj["gain_z"] = c.gain_z;
    cj["rms_before_dph"] = c.rms_before_dph;
    cj["residual_rms_dph"] = c.rms_after_dph;
    cj["rivals"] = Json::array();
    for (const auto& r : c.rivals) {
      Json rj = {{"cause", r.cause}, {"delta_bic", r.delta_bic}};
      if (!r.model.empty()) rj["model"] = r.model;
      cj["rivals"].push_back(rj);
    }
    j["causes"].push_back(cj);
  }
  j["correlations"] = Json::array();
  for (const auto& c : d.correlations) j["correlations"].push_back({{"a", c.a}, {"b", c.b}, {"r", c.r}});
  j["later_steps"] = Json::array();
  for (const auto& st : d.later_steps) j["later_steps"].push_back({{"candidates", CandidatesJson(st)}});
  return j;
}

}  // namespace ssiu
