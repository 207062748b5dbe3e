// `--rate-dps X,Y,Z` and `--exposure-s T`, shared by `ssiu detect`, `ssiu solve` and `ssiu track`:
// the sensor's angular rate during the exposure, handed to the detector as its expected smear
// (detect/smear.h), as the unit's processor does from the gyros.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "core/camera.h"
#include "detect/smear.h"

namespace ssiu::cli {

struct SmearFlags {
  std::string rate_text;  // "X,Y,Z" as given
  double exposure_s = 0;
  CLI::Option* rate = nullptr;
  CLI::Option* exposure = nullptr;
  bool given() const { return rate && rate->count() > 0; }
  bool exposure_given() const { return exposure && exposure->count() > 0; }
};

// Adds the two flags to `cmd`; `axes` says in which axes the rate is read (for the help text).
void AddSmearFlags(CLI::App* cmd, SmearFlags* f, const std::string& axes = "sensor axes");

// The --rate-dps rate in rad/s, checked together with its companions: three finite components, a
// camera (`camera_given`) and a finite --exposure-s in (0, 100) s. InputError naming the flag
// (also for --exposure-s without --rate-dps).
Vec3 SmearRateRadS(const SmearFlags& f, bool camera_given);

// The detector's smear model of a rate (sensor axes) on `camera`; InputError when the smear it
// predicts anywhere in the frame is longer than kMaxSmearPx.
constexpr double kMaxSmearPx = 200;
ExpectedSmear SmearModel(const Vec3& rate_rad_s, double exposure_s, const Camera& camera);

// The detector's smear model from the flags for `camera` (nullptr: no --camera given); inactive
// without either flag. InputError for bad flags.
ExpectedSmear SmearFromFlags(const SmearFlags& f, const Camera* camera);

// InputError when either flag is given to a mode that cannot use it (e.g. `solve --centroids`).
void RefuseSmearFlags(const SmearFlags& f, const std::string& why);

}  // namespace ssiu::cli
