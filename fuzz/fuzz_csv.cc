// libFuzzer harness: the CSV reader (every column requested, with the physical bounds by unit).
#include <cstdint>

#include "core/csv.h"
#include "core/error.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = ssiu::fuzz::InputFile(data, size);
  try {
    const ssiu::CsvTable t = ssiu::ReadCsv(path);
    for (const auto& name : t.header) {
      try {
        const auto& c = t.Column(name);
        if (c.size() != t.rows()) __builtin_trap();
        t.CheckIncreasing(name);
      } catch (const ssiu::InputError&) {
      }
    }
  } catch (const ssiu::InputError&) {
  }
  return 0;
}
