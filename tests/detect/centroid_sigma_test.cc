// The centroid 1-sigma a detection reports must describe its actual error, also when the gain is
// not given (the solver's default): then the fit's weights hold the background noise only and the
// shot noise of bright stars is estimated from the residuals (psf_fit.cc). Stars with shot-noise
// dominated cores, where the plain inverse normal matrix understated the scatter ~1.5-2x.
#include <cmath>

#include "core/image.h"
#include "core/rng.h"
#include "detect/detect.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

TEST(CentroidSigma, NormalisedErrorsNearOneWithoutTheGain) {
  const double gain = 0.5, bias = 200, sky_e = 100, read_e = 10, psf = 1.2;  // electrons; ADU = e / gain
  Rng rng(11);
  double z2 = 0;
  int n = 0;
  for (int frame = 0; frame < 12; ++frame) {
    const int size = 256;
    std::vector<double> e(static_cast<size_t>(size) * size, sky_e);
    struct Truth {
      double x, y;
    };
    std::vector<Truth> truth;
    for (int i = 0; i < 16; ++i) {
      const double x = 24 + 56 * (i % 4) + rng.Uniform(-0.5, 0.5), y = 24 + 56 * (i / 4) + rng.Uniform(-0.5, 0.5);
      const double flux_e = 2e4 * std::pow(10.0, rng.Uniform(0, 1.3));  // SNR ~100-600
      auto frac = [psf](int k, double c) {
        const double a = 1.0 / (std::sqrt(2.0) * psf);
        return 0.5 * (std::erf((k + 0.5 - c) * a) - std::erf((k - 0.5 - c) * a));
      };
      for (int yy = static_cast<int>(y) - 6; yy <= static_cast<int>(y) + 6; ++yy) {
        for (int xx = static_cast<int>(x) - 6; xx <= static_cast<int>(x) + 6; ++xx) {
          e[static_cast<size_t>(yy) * size + xx] += flux_e * frac(xx, x) * frac(yy, y);
        }
      }
      truth.push_back({x, y});
    }
    Image16 img(size, size);
    for (size_t k = 0; k < e.size(); ++k) {
      // Shot noise (Gaussian limit of Poisson) plus read noise, in electrons, then to ADU.
      const double v = e[k] + std::sqrt(e[k] + read_e * read_e) * rng.Normal();
      img.pixels[k] = static_cast<uint16_t>(std::clamp(std::lround(bias + v / gain), 0L, 65535L));
    }
    DetectOptions o;
    o.gain_e_per_adu = 0;  // unknown
    const Detections d = Detect(img.view(), o);
    for (const Truth& t : truth) {
      for (const auto& s : d.stars) {
        if (std::hypot(s.x_px - t.x, s.y_px - t.y) > 1.0 || s.saturated) continue;
        z2 += std::pow((s.x_px - t.x) / s.x_sigma_px, 2) + std::pow((s.y_px - t.y) / s.y_sigma_px, 2);
        n += 2;
      }
    }
  }
  ASSERT_GT(n, 300);
  const double rms_z = std::sqrt(z2 / n);
  RecordProperty("rms_normalised_error", std::to_string(rms_z));
  EXPECT_GT(rms_z, 0.8);
  EXPECT_LT(rms_z, 1.2);
}

}  // namespace
}  // namespace ssiu
