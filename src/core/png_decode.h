// Internal to core: a fast decoder for the PNG kind every simulated and most captured star frames
// are, non-interlaced 8- or 16-bit greyscale. Everything else goes to libpng (raster_codec.h).
// Why: libpng inflates with zlib, which takes ~12 ms of the ~14 ms frame-to-quaternion time of a
// 1 Mpx 16-bit frame; libdeflate's whole-buffer inflate is ~2.5x faster (docs/results.md).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/image.h"

namespace ssiu {

// Decodes `bytes` (a whole PNG file; modified in place: the IDAT payloads are packed together).
// Returns false, leaving `out` and `bytes` alone (it decides before the first IDAT), when the PNG is of
// another kind (colour, palette, grey+alpha, interlaced, 1/2/4-bit, transparency chunk) so the caller
// can fall back; throws InputError naming
// `path` and the failing chunk or field for a corrupt or truncated file (CRC, zlib, sizes).
bool DecodeGreyPng(std::vector<uint8_t>& bytes, const std::string& path, Frame* out);

}  // namespace ssiu
