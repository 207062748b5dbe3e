#include "detect/detect_json.h"

namespace ssiu {

Json DetectionsToJson(const Detections& d, const std::string& file, double scale, double offset) {
  Json j;
  j["file"] = file;
  j["width"] = d.width;
  j["height"] = d.height;
  j["background_adu"] = d.background_adu * scale + offset;
  j["noise_adu"] = d.noise_adu * scale;
  j["psf_sigma_px"] = d.psf_sigma_px;
  j["psf_source"] = d.psf_source;
  j["block_artefacts"] = d.block_artefacts;  // JPEG's 8x8 blocks seen (docs/detection.md)
  j["block_artefact_ratio"] = d.block_artefact_ratio;
  Json stars = Json::array();
  for (const StarDetection& s : d.stars) {
    stars.push_back({{"x_px", s.x_px},
                     {"y_px", s.y_px},
                     {"flux_adu", s.flux_adu * scale},
                     {"peak_adu", s.peak_adu * scale},
                     {"snr", s.snr},
                     {"npix", s.npix},
                     {"saturated", s.saturated},
                     {"sigma_px", s.sigma_px},
                     {"x_sigma_px", s.x_sigma_px},
                     {"y_sigma_px", s.y_sigma_px}});
  }
  j["stars"] = stars;
  Json rej = Json::array();
  for (const Rejection& r : d.rejected) {
    Json jr = {{"x_px", r.x_px}, {"y_px", r.y_px}, {"reason", RejectReasonName(r.reason)}};
    if (!r.detail.empty()) jr["detail"] = r.detail;
    rej.push_back(jr);
  }
  j["rejected"] = rej;
  j["timing_ms"] = d.timing_ms;
  return j;
}

}  // namespace ssiu
