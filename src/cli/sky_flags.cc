#include "cli/sky_flags.h"

#include "core/error.h"

namespace ssiu::cli {

void AddSkyFlags(CLI::App* cmd, SkyFlags* f) {
  cmd->add_option("--time", f->time,
                  "Frame UTC time, ISO 8601 (mid-exposure; default: FITS DATE-OBS): proper motion to that date "
                  "and annual aberration are removed");
  cmd->add_option(
      "--velocity-kms", f->velocity_kms,
      "Spacecraft velocity relative to the Earth, X,Y,Z km/s (ICRS): its aberration is removed too (needs a time)");
}

SkyCorrections SkyFromFlags(const SkyFlags& f, const Frame* frame) {
  SkyCorrections s;
  if (!f.time.empty()) {
    s.time = ParseUtcIso8601(f.time, "--time");
  } else if (frame && !frame->date_obs.empty()) {
    s.time = ParseUtcIso8601(frame->date_obs, frame->file + ": DATE-OBS");
  }
  if (!f.velocity_kms.empty()) {
    s.velocity_m_s = ParseVelocityKms(f.velocity_kms, "--velocity-kms");
    s.have_velocity = true;
    if (!s.time.valid())
      throw InputError("--velocity-kms", "needs the frame time (--time, or a FITS frame's DATE-OBS)");
  }
  s.Check();
  return s;
}

}  // namespace ssiu::cli
