// libFuzzer harness: random call sequences through the C interface of the unit's processor
// (flight/ssiu_flight.h), as a faulty bus or sensor could make them: gyro samples with NaN, inf,
// huge values, times going back or repeating; frames missing, of the wrong size, black, saturated,
// noise, or a star field; state queries; a corrupt catalog blob at init. Every call must return a
// status, and the state, when valid, must be a finite unit quaternion with a finite covariance.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "attitude/star_solver.h"
#include "core/output.h"
#include "flight/flight_config.h"
#include "flight/ssiu_flight.h"
#include "fuzz/fuzz_input.h"
#include "identify/star_catalog.h"

namespace {

// The handle's memory, 16-byte aligned as ssiu_flight_init asks (std::max_align_t is 8 on 32-bit ARM).
struct alignas(16) Block16 {
  unsigned char bytes[16];
};

constexpr int kSize = 96;  // small heads (16.6 deg) keep each frame call short

struct Setup {
  ssiu_flight_config config;
  std::string blob;
  std::vector<uint16_t> stars;  // a frame with a few bright spots
};

const Setup& TheSetup() {
  static const Setup s = [] {
    Setup x;
    ssiu_flight_default_config(&x.config);
    const ssiu::Camera cam = ssiu::MakeCamera(kSize, kSize, 16.6);
    for (int h = 0; h < x.config.n_heads; ++h) {
      x.config.heads[h].width_px = x.config.heads[h].height_px = kSize;
      x.config.heads[h].focal_length_px = cam.focal_length_px;
      x.config.heads[h].cx_px = x.config.heads[h].cy_px = cam.cx_px;
    }
    x.config.exposure_s = 0.1;
    // A small work budget: noise frames run lost in space to its end, and what is fuzzed is the loop's
    // handling of inputs, not the depth of the search (an instrumented build takes ~1000x longer).
    x.config.max_hypotheses = 200;
    x.config.max_patterns = 5000;
    x.blob = ssiu::SolverCatalogBytes(ssiu::MakeIdentifierForCamera("", cam, 0.0).catalog());
    x.config.catalog_crc32 = ssiu::Crc32(x.blob.data(), x.blob.size());
    x.stars.assign(kSize * kSize, 100);
    for (int k = 0; k < 12; ++k) {
      const int cx = 8 + (k * 37) % (kSize - 16), cy = 8 + (k * 53) % (kSize - 16);
      for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx)
          x.stars[(cy + dy) * kSize + cx + dx] = static_cast<uint16_t>(100 + 3000 / (1 + dx * dx + dy * dy));
    }
    return x;
  }();
  return s;
}

struct Reader {
  const uint8_t* d;
  size_t n, i = 0;
  uint8_t Byte() { return i < n ? d[i++] : 0; }
  bool Done() const { return i >= n; }
  // A double that is often ordinary and sometimes not a number at all.
  double Value(double scale) {
    const uint8_t k = Byte();
    switch (k % 16) {
      case 0:
        return std::nan("");
      case 1:
        return HUGE_VAL;
      case 2:
        return -HUGE_VAL;
      case 3:
        return 1e300;
      default:
        return (static_cast<int>(Byte()) - 128) * scale;
    }
  }
};

void Check(bool ok) {
  if (!ok) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const Setup& s = TheSetup();
  Reader r{data, size};
  static std::vector<Block16> memory(ssiu_flight_memory_bytes(&s.config) / sizeof(Block16) + 64);
  ssiu_flight* f = nullptr;
  // One input in 16 starts from a corrupt blob, which init must refuse.
  const uint8_t first = r.Byte();
  if (first % 16 == 0) {
    std::string bad = s.blob;
    bad[(static_cast<size_t>(r.Byte()) * 7919) % bad.size()] ^= static_cast<char>(1 + r.Byte() % 255);
    Check(ssiu_flight_init(&s.config, bad.data(), bad.size(), memory.data(), memory.size() * sizeof(Block16),
                           &f) == SSIU_ERR_CATALOG);
    Check(f == nullptr);
    return 0;
  }
  Check(ssiu_flight_init(&s.config, s.blob.data(), s.blob.size(), memory.data(),
                         memory.size() * sizeof(Block16), &f) == SSIU_OK);
  static std::vector<uint16_t> frame[SSIU_FLIGHT_MAX_HEADS];
  double t = 0;
  int frame_sets = 0;  // at most 24 an input (each may search lost in space on every head)
  for (int ops = 0; ops < 400 && !r.Done(); ++ops) {
    const uint8_t op = r.Byte();
    switch (op % 4) {
      case 0:
      case 1: {  // gyro samples: a step forward, or back, or not a time
        const uint8_t step = r.Byte();
        t += step < 8 ? -0.01 * step : step < 16 ? 0.0 : 0.01;
        if (step == 255) t = std::nan("");
        double g[SSIU_FLIGHT_MAX_GYROS];
        for (int i = 0; i < s.config.n_gyros; ++i) g[i] = r.Value(10.0);
        ssiu_gyro_status st;
        const ssiu_result rc = ssiu_flight_gyro(f, t, g, s.config.n_gyros, &st);
        Check(rc == SSIU_OK && st >= SSIU_GYRO_ACCEPTED && st <= SSIU_GYRO_ACCEPTED_TIME_RESET);
        if (std::isnan(t)) t = 0;
        break;
      }
      case 2: {  // a frame set
        if (++frame_sets > 24) break;
        ssiu_frame fr[SSIU_FLIGHT_MAX_HEADS];
        std::memset(fr, 0, sizeof fr);
        for (int h = 0; h < s.config.n_heads; ++h) {
          const uint8_t kind = r.Byte();
          const int w = kind % 11 == 0 ? kSize - 1 : kSize;
          frame[h].assign(static_cast<size_t>(kSize) * kSize, 0);
          switch (kind % 5) {
            case 0:
              continue;  // no frame
            case 1:
              break;  // black
            case 2:
              frame[h].assign(frame[h].size(), 65535);  // saturated
              break;
            case 3:
              for (auto& p : frame[h]) p = static_cast<uint16_t>(r.Byte() * 257);
              break;
            default:
              frame[h] = s.stars;
          }
          fr[h].pixels = frame[h].data();
          fr[h].width_px = w;
          fr[h].height_px = kSize;
        }
        ssiu_frame_report rep;
        const int32_t n = op % 32 == 2 ? s.config.n_heads + 1 : s.config.n_heads;
        const ssiu_result rc = ssiu_flight_frames(f, t, fr, n, &rep);
        Check(rc == SSIU_OK || (n != s.config.n_heads && rc == SSIU_ERR_ARGUMENT));
        if (rc == SSIU_OK) {
          Check(rep.status >= SSIU_SOLVE_SOLVED && rep.status <= SSIU_SOLVE_BAD_FRAME);
          Check(rep.update_status >= SSIU_UPDATE_ACCEPTED && rep.update_status <= SSIU_UPDATE_NONE);
          for (int h = 0; h < s.config.n_heads; ++h)
            Check(rep.heads[h].status >= SSIU_SOLVE_SOLVED && rep.heads[h].status <= SSIU_SOLVE_BAD_FRAME);
        }
        break;
      }
      default: {
        ssiu_state st;
        Check(ssiu_flight_state(f, &st) == SSIU_OK);
        if (st.valid) {
          double n2 = 0;
          for (double q : st.q_inertial_from_body) n2 += q * q;
          Check(std::isfinite(n2) && std::abs(n2 - 1) < 1e-6);
          for (double c : st.covariance_rad2) Check(std::isfinite(c));
        }
      }
    }
  }
  ssiu_state st;
  Check(ssiu_flight_state(f, &st) == SSIU_OK);
  ssiu_flight_shutdown(f);
  return 0;
}
