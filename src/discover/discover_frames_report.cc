// The JSON of a frame discovery (FrameDiscoveryToJson): the verdict, the chain of named causes, the
// candidates of every step, the fitted camera and the residual's description.
#include "discover/discover_frames.h"

#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/distributions/normal.hpp>
#include <cmath>
#include <limits>

#include "core/astrometry.h"
#include "core/error.h"
#include "core/stats.h"
#include "core/types.h"
#include "discover/discover_frames_internal.h"
#include "discover/discovery_json.h"


namespace ssiu {

namespace {

Json CandidateJson(const FrameCandidate& c) {
  Json cj = {{"cause", c.cause},
             {"statistic", c.statistic},
             {"p_value", c.p_value},
             {"delta_bic", c.delta_bic},
             {"significant", c.significant}};
  if (!c.term.empty()) cj["term"] = c.term;
  if (c.evaluated) {
    cj["gain"] = c.gain;
    cj["gain_z"] = c.gain_z;
    cj["verdict"] = c.verdict;
  }
  return cj;
}

}  // namespace

Json FrameDiscoveryToJson(const FrameDiscovery& d) {
  Json j = discover_internal::DiscoveryVerdictJson(d.cause, d.parameters, d.sigmas, d.gain, d.gain_z, d.gain_z_min,
                                                   d.partial_cause);
  j["fitted_camera"] = CameraToJson(d.fitted_camera);
  AddCameraExtras(d.fitted_camera_extras, &j["fitted_camera"]);
  j["residual_rms_before_arcsec"] = d.residual_rms_before_arcsec;
  j["residual_rms_after_arcsec"] = d.residual_rms_after_arcsec;
  {
    const FrameResidual& r = d.residual;
    Json rj = discover_internal::ResidualVerdictJson(r.structured, r.p_value, r.finding);
    rj.update(Json{{"position_rms_px", r.position_rms_px},
                   {"position_rms_arcsec", r.position_rms_arcsec},
                   {"position_max_px", r.position_max_px},
                   {"position_max_arcsec", r.position_max_arcsec},
                   {"position_max_at_px", {r.position_max_x_px, r.position_max_y_px}},
                   {"position_max_angle_deg", r.position_max_angle_deg},
                   {"position_per_mag_px", r.position_per_mag_px},
                   {"photometry_rms_mag", r.photometry_rms_mag},
                   {"photometry_max_mag", r.photometry_max_mag},
                   {"photometry_max_at_px", {r.photometry_max_x_px, r.photometry_max_y_px}},
                   {"photometry_per_mag", r.photometry_per_mag},
                   {"grid", r.grid},
                   {"worst_cell",
                    {{"centre_px", {r.cell_x_px, r.cell_y_px}},
                     {"stars", r.cell_stars},
                     {"mean_dx_px", r.cell_dx_px},
                     {"mean_dy_px", r.cell_dy_px},
                     {"chi2", r.cell_chi2}}}});
    rj["tests"] = Json::array();
    for (const auto& t : r.tests) {
      rj["tests"].push_back(
          {{"test", t.name}, {"f", t.f}, {"dof", t.dof}, {"dof_residual", t.dof_resid}, {"p_value", t.p_value}});
    }
    j["residual"] = rj;
  }
  j["gain_method"] = d.frames_solved >= 2 ? "held-out frames (even/odd)" : "fitted frame (one frame solved)";
  auto named = [&](const char* cause) {
    return std::any_of(d.causes.begin(), d.causes.end(), [&](const FrameCauseStep& e) { return e.cause == cause; });
  };
  const std::string first = d.causes.empty() ? "" : d.causes.front().cause;
  if (named("psf_shape")) {
    if (first == "psf_shape")
      j["gain_method"] = std::string(d.frames_solved >= 2 ? "held-out frames (even/odd)" : "fitted frame") +
                         ": stamp residual RMS in noise sigmas, model PSF vs fitted shape";
    j["stamp_rms_before"] = d.stamp_rms_before;
    j["stamp_rms_after"] = d.stamp_rms_after;
  }
  if (named("hot_pixels")) {
    if (first == "hot_pixels")
      j["gain_method"] =
          "held-out frames (even/odd): single-pixel spikes per frame, (before + 1) / (after + 1) after "
          "masking the pixels found on the other frames";
    j["spikes_per_frame_before"] = d.spikes_before;
    j["spikes_per_frame_after"] = d.spikes_after;
  }
  j["hot_pixels"] = Json::array();
  for (size_t i = 0; i < d.hot_pixels.size(); ++i) {
    j["hot_pixels"].push_back({{"x_px", d.hot_pixels[i].x},
                               {"y_px", d.hot_pixels[i].y},
                               {"excess_adu", d.hot_pixels[i].excess_adu},
                               {"frames", d.hot_pixel_frames[i]}});
  }
  if (named("vignetting")) {
    j["flux_rms_before_mag"] = d.flux_rms_before_mag;
    j["flux_rms_after_mag"] = d.flux_rms_after_mag;
  }
  j["measured"] = {{"zero_point_adu_v0", d.zero_point_adu},
                   {"photometric_scatter_mag", d.photometric_scatter_mag},
                   {"psf_sigma_median_px", d.psf_sigma_median_px},
                   {"psf_sigma_stamp_fit_px", d.psf_sigma_fit_px},
                   {"psf_e1", d.psf_e1},
                   {"psf_e2", d.psf_e2},
                   {"psf_stars", d.psf_stars},
                   {"background_median_adu", d.background_median_adu},
                   {"noise_median_adu", d.noise_median_adu}};
  j["frames"] = d.frames;
  j["frames_solved"] = d.frames_solved;
  j["stars"] = d.stars;
  j["candidates"] = Json::array();
  for (const auto& c : d.candidates) j["candidates"].push_back(CandidateJson(c));
  j["not_tested"] = d.not_tested;
  // The extended model: the causes in the order they entered (parameters from the final joint fit),
  // every step's candidates, the correlations of the named camera parameters.
  j["causes"] = Json::array();
  for (const auto& e : d.causes) {
    Json ej = discover_internal::DiscoveryVerdictJson(e.cause, e.parameters, e.sigmas, e.gain, e.gain_z,
                                                      d.gain_z_min, "");
    ej.erase("gain_z_min");
    ej.update(Json{{"step", e.step},
                   {"terms", e.terms},
                   {"statistic", e.statistic},
                   {"p_value", e.p_value},
                   {"held_out_before", e.held_out_before},
                   {"held_out_after", e.held_out_after},
                   {"residual_rms_arcsec", e.residual_rms_arcsec}});
    j["causes"].push_back(ej);
  }
  j["steps"] = Json::array();
  for (size_t k = 0; k < d.steps.size(); ++k) {
    Json sj = {{"step", k + 1}, {"candidates", Json::array()}};
    for (const auto& c : d.steps[k]) sj["candidates"].push_back(CandidateJson(c));
    j["steps"].push_back(sj);
  }
  j["removed"] = Json::array();
  for (const auto& r : d.removed) j["removed"].push_back({{"cause", r.cause}, {"term", r.term}, {"p_value", r.p_value}});
  j["correlations"] = Json::array();
  for (const auto& c : d.correlations) j["correlations"].push_back({{"a", c.a}, {"b", c.b}, {"r", c.r}});
  return j;
}


}  // namespace ssiu
