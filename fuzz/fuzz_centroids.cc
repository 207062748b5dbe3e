// libFuzzer harness: the centroid list of `solve --centroids` (x_px,y_px[,flux][,sigma_px]).
#include <cmath>
#include <cstdint>

#include "attitude/star_solver.h"
#include "core/error.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = ssiu::fuzz::InputFile(data, size);
  try {
    for (const auto& c : ssiu::ReadCentroidsCsv(path)) {
      if (!std::isfinite(c.x_px) || !std::isfinite(c.y_px)) __builtin_trap();
    }
  } catch (const ssiu::InputError&) {
  }
  return 0;
}
