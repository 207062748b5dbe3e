// The C interface's configuration (flight/ssiu_flight.h) seen from C++: made from the C++ types
// (`ssiu run --write-frames` writes the mission's unit this way), turned back into them for the
// processor, and as text (DIR/flight.cfg): one `key value...` a line, `#` comments, every key of
// ssiu_flight_config; unknown keys are an error. docs/flight.md.
#pragma once

#include <string>
#include <vector>

#include "core/heads.h"
#include "flight/ssiu_flight.h"
#include "inertial/gyro_unit.h"
#include "inertial/unit_processor.h"

namespace ssiu {

// The flight configuration of a unit with these heads, gyros and processor options (the sky
// corrections' epoch as ISO 8601 UTC, "" = none; velocity in km/s). InputError when it does not fit
// (more heads or gyros than the interface carries, an epoch too long).
ssiu_flight_config FlightConfigFor(const std::vector<OpticalHead>& heads, const GyroUnit& unit,
                                   const UnitProcessorOptions& options, const std::string& epoch_utc,
                                   const Vec3& velocity_kms);

// The processor's C++ inputs from a flight configuration (InputError naming the field when invalid).
struct FlightSetup {
  std::vector<OpticalHead> heads;
  GyroUnit unit;
  UnitProcessorOptions options;
};
FlightSetup FlightSetupFrom(const ssiu_flight_config& config);

std::string FlightConfigText(const ssiu_flight_config& config);
// InputError naming `source`, the line and the key.
ssiu_flight_config ParseFlightConfigText(const std::string& text, const std::string& source);

}  // namespace ssiu
