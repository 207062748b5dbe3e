// libFuzzer harness: the frame readers (PNG fast path and OpenCV, TIFF, FITS via cfitsio) and the
// declared-size check that runs before any pixel is allocated.
#include <cstdint>

#include "core/error.h"
#include "core/image.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = ssiu::fuzz::InputFile(data, size);
  ssiu::ImageLimits limits;
  limits.max_side_px = 2048;  // keeps each run small; the limit itself is what is under test
  limits.max_file_bytes = 1 << 24;
  try {
    const ssiu::Frame f = ssiu::ReadFrame(path, limits);
    if (f.image.width > limits.max_side_px || f.image.height > limits.max_side_px) __builtin_trap();
    if (f.image.pixels.size() != static_cast<size_t>(f.image.width) * f.image.height) __builtin_trap();
  } catch (const ssiu::InputError&) {
  }
  return 0;
}
