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

TEST(RealFrames, AstrometryNetStarsAreFoundWithinOnePixel) {
  SSIU_REQUIRE_SHARED(dir, "openstartracker/astrometry_solutions");
  int total = 0, found = 0;
  for (int k : {0, 2, 3}) {
    const std::string base = testing::SharedData("openstartracker");
    const Frame fr = ReadFrame(base + "/img" + std::to_string(k) + ".png");
    EXPECT_EQ(fr.grey_conversion, "mean_rgb");
    DetectOptions o;
    o.saturation_adu = fr.saturation_adu;
    const Detections d = Detect(fr.image.view(), o);
    const auto corr = ReadCorr(dir + "/img" + std::to_string(k) + ".corr");
    ASSERT_GE(corr.size(), 5u);
    for (const Vec2& c : corr) {
      ++total;
      double best = 1e9;
      for (const auto& s : d.stars) best = std::min(best, std::hypot(s.x_px - c.x(), s.y_px - c.y()));
      found += best <= 1.0;
    }
    // The PSF of these frames is sharp (sigma about 0.55 px): the estimate must see that.
    EXPECT_GT(d.psf_sigma_px, 0.4);
    EXPECT_LT(d.psf_sigma_px, 0.8);
  }
  const double recall = double(found) / total;
  RecordProperty("recall", std::to_string(found) + "/" + std::to_string(total));
  // Measured 39 of 44 (docs/results.md). The five misses, all in img2, are at the noise floor:
  // 2.9-4.3 sigma of the frame's 3x3 box-sum noise, among ~1000 noise peaks of the structured
  // background (lowering the threshold only lets noise peaks crowd them out); astrometry.net found
  // them after subtracting the median frame.
  EXPECT_GE(found, 39) << found << " of " << total;
  EXPECT_GE(recall, 0.88);
}

}  // namespace
}  // namespace ssiu
