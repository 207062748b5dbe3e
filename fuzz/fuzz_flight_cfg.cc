// libFuzzer harness: the flight configuration's text form (flight.cfg, ssiu_flight_parse_config). Any text
// is a configuration or refused with a reason; a configuration is written again (FlightConfigText) and
// reads back to the same text; its check returns a status. No crash, no other exception.
#include <cstdint>
#include <string>

#include "flight/flight_config.h"
#include "flight/ssiu_flight.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ssiu_flight_config c;
  char why[256] = {0};
  const ssiu_result r = ssiu_flight_parse_config(reinterpret_cast<const char*>(data), size, &c, why, sizeof why);
  if (r == SSIU_ERR_CONFIG) {
    if (why[0] == '\0') __builtin_trap();  // a refusal names its line and key
    return 0;
  }
  if (r != SSIU_OK) __builtin_trap();
  const std::string text = ssiu::FlightConfigText(c);
  ssiu_flight_config back;
  if (ssiu_flight_parse_config(text.data(), text.size(), &back, why, sizeof why) != SSIU_OK) __builtin_trap();
  if (ssiu::FlightConfigText(back) != text) __builtin_trap();
  const ssiu_result check = ssiu_flight_check_config(&c);
  if (check != SSIU_OK && check != SSIU_ERR_CONFIG) __builtin_trap();
  return 0;
}
