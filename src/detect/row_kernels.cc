#include "detect/row_kernels.h"

#include <cstring>

// GCC function multi-versioning: an AVX2 clone and a default one, chosen by an ifunc resolver.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define SSIU_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define SSIU_CLONES
#endif

namespace ssiu {

SSIU_CLONES uint16_t RowMin(const uint16_t* __restrict row, int n) {
  uint16_t m = 65535;
  for (int x = 0; x < n; ++x) m = row[x] < m ? row[x] : m;
  return m;
}

SSIU_CLONES void SlideColumnSums(int32_t* __restrict cs, const uint16_t* __restrict add, const uint16_t* __restrict sub,
                                 int n) {
  for (int x = 0; x < n; ++x) cs[x] += static_cast<int32_t>(add[x]) - static_cast<int32_t>(sub[x]);
}

SSIU_CLONES bool BoxAboveThreshold(const int32_t* __restrict cs, const float* __restrict t0, const float* __restrict t1,
                                   float ay, int half, int n, uint8_t* __restrict above) {
  const float by = 1.0f - ay;
  if (half == 1) {
    for (int x = 1; x < n - 1; ++x) {
      const float thr = by * t0[x] + ay * t1[x];
      above[x] = static_cast<float>(cs[x - 1] + cs[x] + cs[x + 1]) > thr;
    }
  } else {
    for (int x = half; x < n - half; ++x) {
      int32_t sum = 0;
      for (int k = -half; k <= half; ++k) sum += cs[x + k];
      const float thr = by * t0[x] + ay * t1[x];
      above[x] = static_cast<float>(sum) > thr;
    }
  }
  const int len = n - 2 * half;
  return len > 0 && std::memchr(above + half, 1, static_cast<size_t>(len)) != nullptr;
}

}  // namespace ssiu
