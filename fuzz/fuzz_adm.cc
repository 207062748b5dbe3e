// libFuzzer harness: the CCSDS AEM/ACM reader (KVN and the small XML reader), and what it reads written
// again in both encodings and read back (a history the reader accepts must be writable).
#include <cstdint>

#include "ccsds/adm.h"
#include "core/error.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = ssiu::fuzz::InputFile(data, size);
  try {
    const ssiu::AttitudeHistory h = ssiu::ReadAdmFile(path);
    if (h.states.empty()) __builtin_trap();
    for (bool xml : {false, true}) {
      const ssiu::AttitudeHistory again = ssiu::ParseAdm(ssiu::FormatAdm(h, h.message, xml), "again", h.epoch_utc);
      if (again.states.size() != h.states.size()) __builtin_trap();
    }
  } catch (const ssiu::InputError&) {
  }
  return 0;
}
