// The JSON form of a detection result (the `ssiu detect` output contract).
#pragma once

#include <string>

#include "core/json.h"
#include "detect/detect.h"

namespace ssiu {

// {"file", "width", "height", "background_adu", "noise_adu", "psf_sigma_px", "stars": [...],
//  "rejected": [...], "timing_ms": {...}}; `scale`/`offset` map stored counts to the file's units.
Json DetectionsToJson(const Detections& d, const std::string& file, double scale = 1.0, double offset = 0.0);

}  // namespace ssiu
