// Real night-sky frames (../shared/data/openstartracker): the stars astrometry.net matched in its
// .corr files must be found within 1 px of their positions.
#include <fitsio.h>

#include <cmath>

#include "core/image.h"
#include "detect/detect.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

// field_x, field_y of an astrometry.net .corr table, converted from FITS (first pixel centre 1,1)
// to ssiu's convention (first pixel centre 0,0).
std::vector<Vec2> ReadCorr(const std::string& path) {
  fitsfile* f = nullptr;
  int status = 0;
  std::vector<Vec2> out;
  if (fits_open_table(&f, path.c_str(), READONLY, &status)) return out;
  long rows = 0;
  int cx = 0, cy = 0;
  fits_get_num_rows(f, &rows, &status);
  fits_get_colnum(f, CASEINSEN, const_cast<char*>("field_x"), &cx, &status);
  fits_get_colnum(f, CASEINSEN, const_cast<char*>("field_y"), &cy, &status);
  std::vector<double> x(rows), y(rows);
  fits_read_col(f, TDOUBLE, cx, 1, 1, rows, nullptr, x.data(), nullptr, &status);
  fits_read_col(f, TDOUBLE, cy, 1, 1, rows, nullptr, y.data(), nullptr, &status);
  fits_close_file(f, &status);
  for (long i = 0; i < rows && status == 0; ++i) out.emplace_back(x[i] - 1.0, y[i] - 1.0);
  return out;
}

struct RecallCount {
  int found = 0, total = 0;
  int chance = 0, chance_total = 0;  // the same positions moved by tens of px: detections there by chance
  size_t max_detections = 0;
};

// Detects img0, img2 and img3 with `o` and counts the .corr stars with a detection within 1 px.
RecallCount CountCorrStarsFound(const std::string& corr_dir, DetectOptions o) {
  RecallCount r;
  for (int k : {0, 2, 3}) {
    const Frame fr = ReadFrame(testing::SharedData("openstartracker") + "/img" + std::to_string(k) + ".png");
    EXPECT_EQ(fr.grey_conversion, "mean_rgb");
    o.saturation_adu = fr.saturation_adu;
    const Detections d = Detect(fr.image.view(), o);
    const auto corr = ReadCorr(corr_dir + "/img" + std::to_string(k) + ".corr");
    EXPECT_GE(corr.size(), 5u);
    auto nearest = [&](const Vec2& c) {
      double best = 1e9;
      for (const auto& s : d.stars) best = std::min(best, std::hypot(s.x_px - c.x(), s.y_px - c.y()));
      return best;
    };
    for (const Vec2& c : corr) {
      ++r.total;
      r.found += nearest(c) <= 1.0;
      for (const Vec2& off : {Vec2(17, -23), Vec2(-31, 12), Vec2(25, 29), Vec2(-14, -37)}) {
        const Vec2 m = c + off;
        if (m.x() < 0 || m.y() < 0 || m.x() > fr.image.width - 1 || m.y() > fr.image.height - 1) continue;
        ++r.chance_total;
        r.chance += nearest(m) <= 1.0;
      }
    }
    r.max_detections = std::max(r.max_detections, d.stars.size());
    // The PSF of these frames is sharp (sigma about 0.55 px): the estimate must see that.
    EXPECT_GT(d.psf_sigma_px, 0.4);
    EXPECT_LT(d.psf_sigma_px, 0.8);
  }
  return r;
}

TEST(RealFrames, AstrometryNetStarsAreFoundWithinOnePixel) {
  SSIU_REQUIRE_SHARED(dir, "openstartracker/astrometry_solutions");
  const RecallCount r = CountCorrStarsFound(dir, DetectOptions{});
  RecordProperty("recall", std::to_string(r.found) + "/" + std::to_string(r.total));
  // Measured 39 of 44 (docs/results.md). The five misses, all in img2, are at the noise floor:
  // 2.9-4.3 sigma of the frame's 3x3 box-sum noise, ranked 700-6900th among the local maxima of
  // the demosaiced frame's correlated noise, below the 1000 brightest sources the default keeps.
  EXPECT_GE(r.found, 39) << r.found << " of " << r.total;
  EXPECT_GE(double(r.found) / r.total, 0.88);
}

// A deep search, as astrometry.net's source list is deep: threshold 3.5 sigma and no cap on the
// number of sources. It finds the faint .corr stars too, and they are not chance coincidences
// among its thousands of detections: the same positions moved by a few tens of pixels meet a
// detection within 1 px at the rate the detection density gives (about 7000 per 1.45 Mpx: 1.6%).
TEST(RealFrames, DeepSearchFindsTheFaintAstrometryNetStars) {
  SSIU_REQUIRE_SHARED(dir, "openstartracker/astrometry_solutions");
  DetectOptions deep;
  deep.threshold_sigma = 3.5;
  deep.max_stars = 100000;
  const RecallCount r = CountCorrStarsFound(dir, deep);
  RecordProperty("deep_recall", std::to_string(r.found) + "/" + std::to_string(r.total));
  RecordProperty("deep_chance", std::to_string(r.chance) + "/" + std::to_string(r.chance_total));
  // Measured 43 of 44; the 44th (img2 723.5,159.9, SNR about 5) is a one-pixel spike at this PSF
  // width (sigma 0.53 px) and noise, rejected as a hot pixel.
  EXPECT_GE(r.found, 43) << r.found << " of " << r.total;
  ASSERT_GT(r.chance_total, 150);
  EXPECT_LT(r.chance, 0.05 * r.chance_total)
      << r.chance << " of " << r.chance_total << " moved positions met a detection";
  EXPECT_GT(r.max_detections, 1000u);  // the deep list really is deeper than the default cap
}

}  // namespace
}  // namespace ssiu
