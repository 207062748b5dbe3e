// Solve overlay PNG: the frame (stretched to 8 bits) with detected stars, matched stars (labelled
// with their star_id), detections left unmatched, rejected interferers and catalog stars predicted
// but not detected. What a user looks at first when a solve fails.
#pragma once

#include <string>

#include "attitude/star_solver.h"
#include "core/image.h"

namespace ssiu {

void WriteSolveOverlay(const std::string& path, const ImageView& image, const Camera& camera, const StarIdentifier& id,
                       const SolveResult& result);

}  // namespace ssiu
