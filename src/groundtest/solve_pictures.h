// The tracker side of a ground test: detect -> identify -> QUEST on each picture (attitude/), written
// as the tracker log `ssiu groundtest compare` reads (t_s,qw,qx,qy,qz,sigma_cross_arcsec,sigma_roll_arcsec).
#pragma once

#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "groundtest/compare.h"

namespace ssiu {

struct PictureSolve {
  SolveStatus status = SolveStatus::kNoMatch;  // as SolveResult::status
  int stars = 0;                               // matched stars
  AttitudeSample sample;                       // valid when solved
};

// gain_e_per_adu: the tracker's gain for shot-noise weights (0 = unknown).
PictureSolve SolveStandPicture(const StarIdentifier& id, const ImageView& image, const Camera& camera,
                               double gain_e_per_adu, double t_s, const SolveOptions& options = {});

void WriteAttitudeCsv(const std::string& path, const std::vector<AttitudeSample>& samples);

}  // namespace ssiu
