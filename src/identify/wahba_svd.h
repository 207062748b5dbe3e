// Wahba's problem by SVD (Markley 1988, "Attitude determination using vector observations and the
// singular value decomposition", J. Astronaut. Sci. 36(3)): the rotation that best maps inertial
// reference directions onto measured sensor directions. Used for hypothesis checks inside
// identification; the reported attitude and its covariance come from QUEST (attitude/quest.h).
#pragma once

#include <cstddef>
#include <vector>

#include "core/types.h"

namespace ssiu {

struct VectorPair {
  Vec3 b_sensor;      // measured unit vector, sensor frame
  Vec3 r_inertial;    // reference unit vector, inertial frame
  double weight = 1;  // e.g. 1 / sigma^2
};

// q_inertial_from_sensor minimising sum w |r - R b|^2. Needs >= 2 non-parallel pairs.
Quat SolveWahbaSvd(const std::vector<VectorPair>& pairs);
// The same over the n pairs at `pairs` (allocates nothing).
Quat SolveWahbaSvd(const VectorPair* pairs, size_t n);

}  // namespace ssiu
