// libFuzzer harness: the strict JSON reader (duplicate keys, nesting), then the camera.json reader and
// the heads.json entry reader on whatever it parses; a camera that passes must be usable (finite focal
// length, projectable centre) and a head's mount a unit quaternion.
#include <cmath>
#include <cstdint>

#include "core/camera.h"
#include "core/error.h"
#include "core/json.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string& path = ssiu::fuzz::InputFile(data, size);
  try {
    const ssiu::Json j = ssiu::ReadJsonFile(path);
    try {
      const ssiu::Camera c = ssiu::CameraFromJson(j, path);
      if (!(c.focal_length_px > 0) || c.width < 16 || c.height < 16) __builtin_trap();
      (void)c.Unproject(ssiu::Vec2(c.cx_px, c.cy_px));
    } catch (const ssiu::InputError&) {
    }
    if (j.is_array()) {
      for (const auto& h : j) {
        ssiu::Camera c;
        ssiu::Quat q;
        ssiu::HeadFromJson(h, path, &c, &q);
        if (!(std::abs(q.norm() - 1) < 1e-6) || !(c.focal_length_px > 0)) __builtin_trap();
      }
    }
  } catch (const ssiu::InputError&) {
  }
  return 0;
}
