#include "core/image.h"

#include <fstream>

#include "core/error.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

Image16 Ramp(int w, int h) {
  Image16 im(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) im.at(x, y) = static_cast<uint16_t>(100 + 7 * x + 13 * y);
  return im;
}

std::string ErrorOf(const std::string& path) {
  try {
    ReadFrame(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(Image, Png16AndFitsRoundTripWithTopLeftOrigin) {
  const std::string dir = testing::TempDir("img");
  const Image16 im = Ramp(40, 30);
  WritePng16(dir + "/a.png", im);
  WriteFits16(dir + "/a.fits", im);
  for (const std::string f : {"/a.png", "/a.fits"}) {
    const Frame fr = ReadFrame(dir + f);
    ASSERT_EQ(fr.image.width, 40);
    ASSERT_EQ(fr.image.height, 30);
    EXPECT_EQ(fr.image.at(0, 0), 100);
    EXPECT_EQ(fr.image.at(39, 0), 100 + 7 * 39);
    EXPECT_EQ(fr.image.at(0, 29), 100 + 13 * 29);
    EXPECT_EQ(fr.bit_depth, 16);
  }
}

TEST(Image, BadFilesGiveOneLineErrorsNamingTheFile) {
  const std::string dir = testing::TempDir("img");
  EXPECT_THAT(ErrorOf(dir + "/none.png"), ::testing::HasSubstr("none.png: no such file"));
  std::ofstream(dir + "/empty.png").close();
  EXPECT_THAT(ErrorOf(dir + "/empty.png"), ::testing::HasSubstr("empty.png: file is empty"));
  std::ofstream(dir + "/text.png") << "this is not an image";
  EXPECT_THAT(ErrorOf(dir + "/text.png"), ::testing::HasSubstr("text.png: cannot decode"));
  // Truncated PNG: the first half of a valid file.
  WritePng16(dir + "/full.png", Ramp(200, 200));
  std::ifstream in(dir + "/full.png", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(dir + "/trunc.png", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  EXPECT_THAT(ErrorOf(dir + "/trunc.png"), ::testing::HasSubstr("trunc.png"));
  // Truncated FITS.
  WriteFits16(dir + "/full.fits", Ramp(200, 200));
  std::ifstream fin(dir + "/full.fits", std::ios::binary);
  std::string fb((std::istreambuf_iterator<char>(fin)), std::istreambuf_iterator<char>());
  std::ofstream(dir + "/trunc.fits", std::ios::binary) << fb.substr(0, 4000);
  EXPECT_THAT(ErrorOf(dir + "/trunc.fits"), ::testing::HasSubstr("trunc.fits"));
  // All-zero and all-saturated.
  WritePng16(dir + "/zero.png", Image16(64, 64, 0));
  EXPECT_THAT(ErrorOf(dir + "/zero.png"), ::testing::HasSubstr("constant"));
  WritePng16(dir + "/sat.png", Image16(64, 64, 65535));
  EXPECT_THAT(ErrorOf(dir + "/sat.png"), ::testing::HasSubstr("constant"));
  Image16 mostly(64, 64, 65535);
  mostly.at(3, 3) = 100;
  WritePng16(dir + "/mostly.png", mostly);
  EXPECT_THAT(ErrorOf(dir + "/mostly.png"), ::testing::HasSubstr("saturated"));
}

}  // namespace
}  // namespace ssiu
