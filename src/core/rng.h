// Deterministic random numbers: the same seed gives the same stream on every platform
// (std::mt19937_64 is fully specified; the std distributions are not, so they are not used).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

namespace ssiu {

class Rng {
 public:
  explicit Rng(uint64_t seed) : gen_(seed) {}
  // Uniform in [0, 1).
  double Uniform() { return static_cast<double>(gen_() >> 11) * (1.0 / 9007199254740992.0); }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  // Standard normal (Marsaglia polar method).
  double Normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u, v, s;
    do {
      u = 2 * Uniform() - 1;
      v = 2 * Uniform() - 1;
      s = u * u + v * v;
    } while (s >= 1 || s == 0);
    const double m = std::sqrt(-2 * std::log(s) / s);
    spare_ = v * m;
    has_spare_ = true;
    return u * m;
  }
  // Poisson: Knuth's product method for small means, normal approximation above 40 (whose
  // distribution error there is far below the other noise terms of a CCD frame).
  double Poisson(double mean) {
    if (mean <= 0) return 0;
    if (mean > 40) return std::max(0.0, std::round(mean + std::sqrt(mean) * Normal()));
    const double l = std::exp(-mean);
    double p = 1;
    int k = 0;
    do {
      ++k;
      p *= Uniform();
    } while (p > l);
    return k - 1;
  }
  uint64_t NextU64() { return gen_(); }

 private:
  std::mt19937_64 gen_;
  bool has_spare_ = false;
  double spare_ = 0;
};

}  // namespace ssiu
