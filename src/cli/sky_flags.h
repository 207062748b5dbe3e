// `--time ISO8601` and `--velocity-kms X,Y,Z`, shared by `ssiu solve` and `ssiu track`: the frame's
// UTC time (else a FITS frame's DATE-OBS) and the spacecraft's velocity relative to the Earth (ICRS),
// from which the solver brings catalog stars to their apparent directions (core/astrometry.h).
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "core/astrometry.h"
#include "core/image.h"

namespace ssiu::cli {

struct SkyFlags {
  std::string time, velocity_kms;
};

void AddSkyFlags(CLI::App* cmd, SkyFlags* f);

// The corrections for a frame: --time, else `frame`'s DATE-OBS (frame may be null), else none;
// --velocity-kms with them. InputError naming the flag or the file's DATE-OBS.
SkyCorrections SkyFromFlags(const SkyFlags& f, const Frame* frame);

}  // namespace ssiu::cli
