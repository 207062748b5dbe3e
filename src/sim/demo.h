// The main job on the built-in default (README's first command): simulate a frame at a random
// attitude from the catalog, run the pipeline on it and measure the result against the truth.
#pragma once

#include <cstdint>
#include <string>

#include "core/catalog.h"
#include "core/json.h"

namespace ssiu {

struct DemoReport {
  std::string text;  // human summary
  Json json;         // the same figures, machine-readable
};

DemoReport RunDemo(const StarCatalog& catalog, uint64_t seed);

}  // namespace ssiu
