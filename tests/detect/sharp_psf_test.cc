// Undersampled stars (PSF sigma ~0.55 px, as on the openstartracker frames) with noise pixels a few
// pixels out must stay stars: the shape test measures elongation within 2.5 fitted sigma, not over
// the whole fit window, where two noise pixels made a round star look elongated (a 14-sigma star
// of img2 was rejected as `extended/elongated` that way).
#include <cmath>

#include "core/image.h"
#include "core/rng.h"
#include "detect/detect.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// Pixel-integrated circular Gaussian of total flux f and sigma s centred at (cx, cy), added to img.
void AddStar(Image16* img, double cx, double cy, double f, double s) {
  auto frac = [s](int k, double c) {
    const double a = 1.0 / (std::sqrt(2.0) * s);
    return 0.5 * (std::erf((k + 0.5 - c) * a) - std::erf((k - 0.5 - c) * a));
  };
  for (int y = static_cast<int>(cy) - 4; y <= static_cast<int>(cy) + 4; ++y) {
    for (int x = static_cast<int>(cx) - 4; x <= static_cast<int>(cx) + 4; ++x) {
      img->at(x, y) = static_cast<uint16_t>(std::lround(img->at(x, y) + f * frac(x, cx) * frac(y, cy)));
    }
  }
}

TEST(SharpPsf, RoundStarWithNoisePixelsNearbyIsAStarNotElongated) {
  Image16 img(256, 256);
  Rng rng(5);
  for (auto& p : img.pixels) p = static_cast<uint16_t>(std::lround(100 + 2.0 * rng.Normal()));
  struct Truth {
    double x, y;
  };
  std::vector<Truth> truth;
  for (int i = 0; i < 16; ++i) {
    const double x = 24 + 56 * (i % 4) + rng.Uniform(-0.5, 0.5), y = 24 + 56 * (i / 4) + rng.Uniform(-0.5, 0.5);
    AddStar(&img, x, y, 120.0, 0.55);  // peak 30-50 ADU over noise 2: 14-20 sigma in the box sum
    // Two positive noise pixels 3 px out, as next to the img2 star: 6.5 and 4 sigma.
    const int ix = static_cast<int>(std::lround(x)), iy = static_cast<int>(std::lround(y));
    img.at(ix + 2, iy - 3) += 13;
    img.at(ix - 3, iy + 1) += 8;
    truth.push_back({x, y});
  }
  DetectOptions o;
  o.psf_sigma_px = 0;  // estimated from the frame, as for real frames
  const Detections d = Detect(img.view(), o);
  int found = 0;
  for (const Truth& t : truth) {
    double best = 1e9;
    for (const auto& s : d.stars) best = std::min(best, std::hypot(s.x_px - t.x, s.y_px - t.y));
    found += best < 0.3;
  }
  int elongated = 0;
  for (const auto& r : d.rejected) elongated += r.detail == "elongated";
  EXPECT_EQ(found, 16);
  EXPECT_EQ(elongated, 0);
  EXPECT_LT(d.psf_sigma_px, 0.8);
}

}  // namespace
}  // namespace ssiu
