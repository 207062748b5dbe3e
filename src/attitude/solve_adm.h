// Star-tracker solutions with their times as a CCSDS attitude history (ccsds/adm.h), for `ssiu track
// --aem/--acm` and a batch `ssiu solve --aem/--acm`: the sensor frame (AST_<head>) relative to ICRF,
// each solution's covariance as COV_TYPE ANGLE (sensor axes), and AD_METHOD QUEST with the head's
// median 1-sigma noise and its rate.
#pragma once

#include <string>
#include <vector>

#include "attitude/quest.h"
#include "ccsds/adm.h"
#include "core/astrometry.h"

namespace ssiu {

struct TimedAttitude {
  UtcTime time;  // the frame's time (mid-exposure)
  AttitudeSolution attitude;
};

// The solved ones in time order, t_s after the first one's time (epoch_utc: that time to the
// millisecond). InputError (naming `where`) for a solution without a time, two at the same time, or none.
AttitudeHistory SolvedAttitudeHistory(std::vector<TimedAttitude> solutions, const std::string& where, int head = 1);

}  // namespace ssiu
