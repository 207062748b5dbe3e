// The detector with an expected smear (DetectOptions::smear): sources smeared along the predicted
// direction by the predicted length are stars, centred on the middle of their path; sources of the
// same flux smeared across it or three times as long are rejected, as is a sharp cosmic-ray track
// along it. Frames drawn here (Gaussian sub-images along a segment, independent of the detector's
// model), with Gaussian noise.
#include <cmath>
#include <cstdio>
#include <vector>

#include "core/camera.h"
#include "core/image.h"
#include "core/rng.h"
#include "detect/detect.h"
#include "detect/psf_fit.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

constexpr double kSigmaPx = 1.2, kBackground = 500, kNoise = 8;

// Adds `flux` ADU of a circular Gaussian (sigma s, evaluated at pixel centres and normalised) smeared
// uniformly from (x0, y0) to (x1, y1), sampled every 0.05 px.
void AddSmear(std::vector<double>& img, int w, double x0, double y0, double x1, double y1, double flux, double s) {
  const int n = std::max(1, static_cast<int>(std::ceil(std::hypot(x1 - x0, y1 - y0) / 0.05)));
  for (int k = 0; k < n; ++k) {
    const double t = (k + 0.5) / n, x = x0 + t * (x1 - x0), y = y0 + t * (y1 - y0);
    for (int j = static_cast<int>(y) - 8; j <= static_cast<int>(y) + 8; ++j) {
      for (int i = static_cast<int>(x) - 8; i <= static_cast<int>(x) + 8; ++i) {
        const double r2 = (i - x) * (i - x) + (j - y) * (j - y);
        img[static_cast<size_t>(j) * w + i] += flux / n * std::exp(-r2 / (2 * s * s)) / (2 * kPi * s * s);
      }
    }
  }
}

Image16 ToImage(const std::vector<double>& signal, int w, int h, uint64_t seed) {
  Rng rng(seed);
  Image16 im(w, h);
  for (size_t i = 0; i < signal.size(); ++i) {
    im.pixels[i] =
        static_cast<uint16_t>(std::lround(std::clamp(kBackground + signal[i] + kNoise * rng.Normal(), 0.0, 65535.0)));
  }
  return im;
}

TEST(SmearFit, AcceptsThePredictedSmearAndRejectsOthers) {
  const Camera cam = MakeCamera(512, 512, 16.6);
  ExpectedSmear smear;
  smear.rate_rad_s = Vec3(2.0 * kDegToRad, 0, 0);  // about +X: stars run along +y
  smear.exposure_s = 0.1;
  smear.camera = cam;
  const int w = cam.width, h = cam.height;
  std::vector<double> sig(static_cast<size_t>(w) * h, 0.0);
  const double flux = 20000;  // SNR ~100
  // Stars on a grid, each smeared as predicted at its position.
  std::vector<Vec2> stars;
  for (int gy = 0; gy < 4; ++gy) {
    for (int gx = 0; gx < 4; ++gx) {
      const Vec2 p(60.3 + 110 * gx + 0.17 * gy, 50.6 + 110 * gy + 0.29 * gx);
      const Vec2 d = smear.DisplacementPx(p);
      ASSERT_NEAR(d.y(), 6.1, 0.2);
      AddSmear(sig, w, p.x() - 0.5 * d.x(), p.y() - 0.5 * d.y(), p.x() + 0.5 * d.x(), p.y() + 0.5 * d.y(), flux,
               kSigmaPx);
      stars.push_back(p);
    }
  }
  // Impostors between the stars: across the predicted direction, three times too long, and a sharp
  // (unblurred) track along it.
  const Vec2 across(115.4, 105.2), longer(225.7, 215.3), sharp(335.2, 325.8);
  AddSmear(sig, w, across.x() - 3.05, across.y(), across.x() + 3.05, across.y(), flux, kSigmaPx);
  AddSmear(sig, w, longer.x(), longer.y() - 9.2, longer.x(), longer.y() + 9.2, flux, kSigmaPx);
  AddSmear(sig, w, sharp.x(), sharp.y() - 3.05, sharp.x(), sharp.y() + 3.05, flux, 0.35);
  const Image16 im = ToImage(sig, w, h, 5);

  DetectOptions o;
  o.psf_sigma_px = kSigmaPx;
  const Detections blind = Detect(im.view(), o);
  o.smear = smear;
  const Detections d = Detect(im.view(), o);
  auto nearest = [](const Detections& det, const Vec2& p) {
    double best = 1e9;
    for (const auto& s : det.stars) best = std::min(best, std::hypot(s.x_px - p.x(), s.y_px - p.y()));
    return best;
  };
  int found = 0, found_blind = 0;
  double err2 = 0, err2_blind = 0;
  for (const Vec2& p : stars) {
    const double e = nearest(d, p), eb = nearest(blind, p);
    found += e < 1.0;
    found_blind += eb < 1.0;
    err2 += e * e;
    err2_blind += eb * eb;
  }
  std::printf("rate given: %d of 16, error RMS %.3f px; not given: %d, %.3f px\n", found, std::sqrt(err2 / 16),
              found_blind, std::sqrt(err2_blind / 16));
  EXPECT_EQ(found, 16);
  // SNR ~450: the smeared model centres them within 0.02 px; the still model, fitted in a window
  // that cuts the smear, is off by several times that.
  EXPECT_LT(std::sqrt(err2 / 16), 0.02);
  EXPECT_GT(std::sqrt(err2_blind / 16), 3 * std::sqrt(err2 / 16));
  EXPECT_GT(nearest(d, across), 5.0) << "smear across the predicted direction taken for a star";
  EXPECT_GT(nearest(d, longer), 5.0) << "smear three times the predicted length taken for a star";
  EXPECT_GT(nearest(d, sharp), 5.0) << "sharp track taken for a star";
  for (const auto& s : d.stars) {  // nothing else but noise peaks at the threshold
    bool is_star = false;
    for (const Vec2& p : stars) is_star = is_star || std::hypot(s.x_px - p.x(), s.y_px - p.y()) < 1.0;
    if (!is_star) {
      EXPECT_LT(s.snr, 8.0) << "unexpected source at " << s.x_px << ", " << s.y_px;
    }
  }
}

// The smeared fit alone on noise-free smears of every direction: centre to 0.002 px and flux to 0.5%
// (the drawn PSF is point-sampled, the model pixel-integrated, which only moves the fitted sigma), and
// the elongation against the smeared model is 1.
TEST(SmearFit, NoiseFreeSmearsOfEveryDirectionAreCentred) {
  const int w = 64, h = 64;
  for (int k = 0; k < 8; ++k) {
    const double th = k * kPi / 8, len = 8.0, flux = 50000;
    const double x = 31.3 + 0.1 * k, y = 32.6 - 0.07 * k, dx = len * std::cos(th), dy = len * std::sin(th);
    std::vector<double> sig(static_cast<size_t>(w) * h, 0.0);
    AddSmear(sig, w, x - 0.5 * dx, y - 0.5 * dy, x + 0.5 * dx, y + 0.5 * dy, flux, kSigmaPx);
    Image16 im(w, h);
    for (size_t i = 0; i < sig.size(); ++i) im.pixels[i] = static_cast<uint16_t>(std::lround(kBackground + sig[i]));
    PsfFitOptions fo;
    fo.smear_dx_px = dx;
    fo.smear_dy_px = dy;
    const PsfFit f = FitPsf(im.view(), static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y)), 3,
                            kBackground, 1.0, fo, [](int, int) { return false; });
    ASSERT_TRUE(f.ok) << k;
    EXPECT_NEAR(f.x_px, x, 0.002) << k;
    EXPECT_NEAR(f.y_px, y, 0.002) << k;
    EXPECT_NEAR(f.flux_adu, flux, 0.005 * flux) << k;
    EXPECT_LT(f.elongation, 1.1) << k;
    // The still fit of the same image, for contrast: its window cuts the smear and it looks elongated.
    const PsfFit still = FitPsf(im.view(), static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y)), 3,
                                kBackground, 1.0, PsfFitOptions{}, [](int, int) { return false; });
    EXPECT_GT(still.elongation, 1.5) << k;
  }
}

}  // namespace
}  // namespace ssiu
