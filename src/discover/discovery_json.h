// The JSON fields that `ssiu discover gyro` and `ssiu discover frames` share (docs/discrepancy.md), written
// once: the verdict (the named cause, its parameters with 1-sigmas, the held-out gain, its z and the
// gate on it, the partial cause of an `unexplained`) and the head of the residual's report. Each
// report adds its own fields (units differ: dph for gyro logs, arcsec and px for frames).
#pragma once

#include <map>
#include <string>

#include "core/json.h"

namespace ssiu::discover_internal {

inline Json DiscoveryVerdictJson(const std::string& cause, const std::map<std::string, double>& parameters,
                                 const std::map<std::string, double>& sigmas, double gain, double gain_z,
                                 double gain_z_min, const std::string& partial_cause) {
  Json j;
  j["cause"] = cause;
  j["parameters"] = Json::object();
  for (const auto& [k, v] : parameters) j["parameters"][k] = v;
  j["parameter_sigmas"] = Json::object();
  for (const auto& [k, v] : sigmas) j["parameter_sigmas"][k] = v;
  j["gain"] = gain;
  j["gain_z"] = gain_z;
  j["gain_z_min"] = gain_z_min;
  if (!partial_cause.empty()) j["partial_cause"] = partial_cause;
  return j;
}

// The residual's verdict: structure left (at the residual alpha), its family-wise p-value and the test
// that found it.
inline Json ResidualVerdictJson(bool structured, double p_value, const std::string& finding) {
  return {{"structured", structured}, {"p_value", p_value}, {"finding", finding}};
}

}  // namespace ssiu::discover_internal
