#include "core/image.h"

#include <libdeflate.h>

#include <algorithm>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "core/error.h"
#include "core/image_cv.h"
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
  // A FITS header that declares 16000x16000 pixels over one block of data: refused from the file
  // size, before gigabytes are allocated for the read; 65536x65536 is refused by the size limit first.
  for (const std::string side : {"16000", "65536"}) {
    auto card = [](const std::string& c) { return c + std::string(80 - c.size(), ' '); };
    std::string h = card("SIMPLE  =                    T") + card("BITPIX  =                   16") +
                    card("NAXIS   =                    2") + card("NAXIS1  =                " + side) +
                    card("NAXIS2  =                " + side) + card("END");
    h += std::string(2880 - h.size(), ' ') + std::string(2880, '\0');
    std::ofstream(dir + "/liar.fits", std::ios::binary) << h;
    EXPECT_THAT(
        ErrorOf(dir + "/liar.fits"),
        ::testing::HasSubstr(side == "16000" ? "liar.fits: FITS data is shorter than its header"
                                             : "liar.fits: declares 65536 x 65536 pixels, more than the limit"));
  }
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

// The fast grey-PNG decoder behind ReadFrame, checked against images whose pixels are known: the
// files are written by a small encoder here that picks each row's filter and splits the data
// into IDAT chunks of chosen sizes (OpenCV's writer always uses one filter), and OpenCV's own
// libpng reader must agree on every file.

void PutBe32(std::string* s, uint32_t v) {
  for (int k = 3; k >= 0; --k) s->push_back(static_cast<char>((v >> (8 * k)) & 0xff));
}

void PutChunk(std::string* s, const std::string& type, const std::string& data) {
  PutBe32(s, static_cast<uint32_t>(data.size()));
  const std::string td = type + data;
  s->append(td);
  PutBe32(s, libdeflate_crc32(0, td.data(), td.size()));
}

int Paeth(int a, int b, int c) {
  const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return (pa <= pb && pa <= pc) ? a : (pb <= pc ? b : c);
}

// PNG (ISO/IEC 15948) of `im` at 8 or 16 bits; row y uses filter filters[y % size]; the zlib
// stream is cut into IDAT chunks of `idat_bytes`; a text chunk sits between IHDR and IDAT.
std::string EncodeGreyPng(const Image16& im, int depth, const std::vector<int>& filters, size_t idat_bytes) {
  const int bpp = depth / 8;
  const size_t rb = static_cast<size_t>(im.width) * bpp;
  std::vector<uint8_t> raw, prev(rb, 0), cur(rb);
  for (int y = 0; y < im.height; ++y) {
    for (int x = 0; x < im.width; ++x) {
      const uint16_t v = im.at(x, y);
      if (depth == 16) {
        cur[2 * x] = static_cast<uint8_t>(v >> 8);
        cur[2 * x + 1] = static_cast<uint8_t>(v & 0xff);
      } else {
        cur[x] = static_cast<uint8_t>(v);
      }
    }
    const int f = filters[y % filters.size()];
    raw.push_back(static_cast<uint8_t>(f));
    for (size_t i = 0; i < rb; ++i) {
      const int a = i >= static_cast<size_t>(bpp) ? cur[i - bpp] : 0;
      const int b = prev[i];
      const int c = i >= static_cast<size_t>(bpp) ? prev[i - bpp] : 0;
      const int pred = f == 0 ? 0 : f == 1 ? a : f == 2 ? b : f == 3 ? (a + b) / 2 : Paeth(a, b, c);
      raw.push_back(static_cast<uint8_t>(cur[i] - pred));
    }
    prev = cur;
  }
  libdeflate_compressor* comp = libdeflate_alloc_compressor(6);
  std::string z(libdeflate_zlib_compress_bound(comp, raw.size()), '\0');
  z.resize(libdeflate_zlib_compress(comp, raw.data(), raw.size(), z.data(), z.size()));
  libdeflate_free_compressor(comp);
  std::string png("\x89PNG\r\n\x1a\n", 8), ihdr;
  PutBe32(&ihdr, static_cast<uint32_t>(im.width));
  PutBe32(&ihdr, static_cast<uint32_t>(im.height));
  ihdr += std::string{static_cast<char>(depth), 0, 0, 0, 0};
  PutChunk(&png, "IHDR", ihdr);
  PutChunk(&png, "tEXt", std::string("Comment\0ssiu test", 17));
  for (size_t i = 0; i < z.size(); i += idat_bytes) PutChunk(&png, "IDAT", z.substr(i, idat_bytes));
  PutChunk(&png, "IEND", "");
  return png;
}

Image16 Noisy(int w, int h, int depth, unsigned seed) {
  std::mt19937 rng(seed);
  const int top = depth == 16 ? 65535 : 255;
  std::uniform_int_distribution<int> step(-top / 20, top / 20);
  Image16 im(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int base = x > 0 ? im.at(x - 1, y) : (y > 0 ? im.at(0, y - 1) : top / 2);
      im.at(x, y) = static_cast<uint16_t>(std::clamp(base + step(rng), 0, top));
    }
  im.at(0, 0) = 0;  // full range, so no byte is constant
  im.at(w - 1, h - 1) = static_cast<uint16_t>(top);
  return im;
}

std::string WriteFile(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

TEST(PngDecode, EveryFilterDepthAndOddWidthDecodesToTheEncodedPixels) {
  const std::string dir = testing::TempDir("pngdec");
  const std::vector<std::vector<int>> filter_sets = {{0}, {1}, {2}, {3}, {4}, {4, 1, 0, 3, 2}};
  int n = 0;
  for (int depth : {8, 16}) {
    for (int w : {1, 7, 16, 17, 33, 100}) {
      for (const auto& filters : filter_sets) {
        const Image16 im = Noisy(w, 9, depth, static_cast<unsigned>(100 * depth + w));
        const std::string path =
            WriteFile(dir + "/f" + std::to_string(n++) + ".png", EncodeGreyPng(im, depth, filters, 1 + (w * 5) % 37));
        const Frame fr = ReadFrame(path);
        ASSERT_EQ(fr.image.width, w);
        ASSERT_EQ(fr.image.height, 9);
        EXPECT_EQ(fr.bit_depth, depth);
        EXPECT_EQ(fr.saturation_adu, depth == 8 ? 255 : 65535);
        EXPECT_EQ(fr.image.pixels, im.pixels) << "depth " << depth << " width " << w << " filters " << filters[0];
        // The reference decoder (libpng through OpenCV) reads the same pixels from the file.
        const cv::Mat m = cv::imread(path, cv::IMREAD_UNCHANGED);
        ASSERT_EQ(m.depth(), depth == 8 ? CV_8U : CV_16U);
        for (int y = 0; y < m.rows; ++y)
          for (int x = 0; x < m.cols; ++x) {
            const int v = depth == 8 ? m.at<uint8_t>(y, x) : m.at<uint16_t>(y, x);
            ASSERT_EQ(v, im.at(x, y)) << path << " (" << x << "," << y << ")";
          }
      }
    }
  }
}

TEST(PngDecode, LargeFrameWrittenByOpenCvMatches) {
  const std::string dir = testing::TempDir("pngdec");
  const Image16 im = Noisy(1024, 64, 16, 7);
  WritePng16(dir + "/big.png", im);
  EXPECT_EQ(ReadFrame(dir + "/big.png").image.pixels, im.pixels);
}

TEST(PngDecode, CorruptFilesGiveAnErrorNamingFileAndField) {
  const std::string dir = testing::TempDir("pngdec");
  const Image16 im = Noisy(40, 20, 16, 3);
  const std::string good = EncodeGreyPng(im, 16, {1}, 200);
  const size_t first_idat = good.find("IDAT");
  ASSERT_NE(first_idat, std::string::npos);

  std::string bad_crc = good;
  bad_crc[first_idat + 10] ^= 0x40;  // a payload byte: the chunk's CRC no longer matches
  EXPECT_THAT(ErrorOf(WriteFile(dir + "/crc.png", bad_crc)),
              ::testing::AllOf(::testing::HasSubstr("crc.png"), ::testing::HasSubstr("'IDAT' fails its CRC")));

  EXPECT_THAT(ErrorOf(WriteFile(dir + "/cut.png", good.substr(0, first_idat + 100))),
              ::testing::AllOf(::testing::HasSubstr("cut.png"), ::testing::HasSubstr("truncated")));

  // Valid chunks whose zlib data describe fewer rows than IHDR declares.
  Image16 shorter(40, 19);
  std::copy(im.pixels.begin(), im.pixels.begin() + 40 * 19, shorter.pixels.begin());
  std::string short_data = EncodeGreyPng(shorter, 16, {1}, 200);
  const std::string tall = EncodeGreyPng(im, 16, {1}, 200);
  short_data.replace(8, 25, tall.substr(8, 25));  // IHDR (with CRC) of the 20-row image
  EXPECT_THAT(ErrorOf(WriteFile(dir + "/short.png", short_data)), ::testing::HasSubstr("fewer bytes than IHDR"));

  // A filter type outside 0..4.
  EXPECT_THAT(ErrorOf(WriteFile(dir + "/filt.png", EncodeGreyPng(im, 16, {1, 7}, 200))),
              ::testing::HasSubstr("row 1 has unknown filter type 7"));

  std::string no_idat("\x89PNG\r\n\x1a\n", 8);
  no_idat += good.substr(8, 25);
  PutChunk(&no_idat, "IEND", "");
  EXPECT_THAT(ErrorOf(WriteFile(dir + "/empty_idat.png", no_idat)), ::testing::HasSubstr("no IDAT"));
}

TEST(PngDecode, ColourPngIsReducedToTheMeanOfRgb) {
  const std::string dir = testing::TempDir("pngdec");
  cv::Mat rgb(8, 8, CV_8UC3, cv::Scalar(30, 60, 90));
  rgb.at<cv::Vec3b>(2, 3) = cv::Vec3b(3, 6, 9);
  ASSERT_TRUE(cv::imwrite(dir + "/rgb.png", rgb));
  const Frame fr = ReadFrame(dir + "/rgb.png");
  EXPECT_EQ(fr.grey_conversion, "mean_rgb");
  EXPECT_EQ(fr.image.at(0, 0), 60);
  EXPECT_EQ(fr.image.at(3, 2), 6);
}

// ssiu reads PNG and TIFF with libpng/libtiff and writes PNG with its own encoder (no OpenCV codec at
// run time); OpenCV's codecs are the independent reference: every kind they write is read as they
// read it (grey kept, colour to the rounded mean of R, G, B), and what ssiu writes they read back.
TEST(RasterCodec, PngAndTiffOfEveryDepthAndChannelCountMatchOpenCv) {
  const std::string dir = testing::TempDir("codec");
  std::mt19937 rng(5);
  int n = 0;
  for (int type : {CV_8UC1, CV_16UC1, CV_8UC3, CV_16UC3, CV_8UC4, CV_16UC4}) {
    cv::Mat m(23, 37, type);
    cv::randu(m, 0, CV_MAT_DEPTH(type) == CV_8U ? 256 : 65536);
    // ssiu's PNG encoder: the reference decoder reads back every sample.
    const std::string png = PngBytes(m);
    const cv::Mat back = cv::imdecode(std::vector<uchar>(png.begin(), png.end()), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(back.type(), type);
    EXPECT_EQ(cv::norm(back, m, cv::NORM_INF), 0) << "PngBytes type " << type;
    for (const std::string ext : {".png", ".tiff", "_ssiu.png"}) {
      const std::string path = dir + "/f" + std::to_string(n++) + ext;
      if (ext == "_ssiu.png") {
        std::ofstream(path, std::ios::binary) << png;
      } else {
        ASSERT_TRUE(cv::imwrite(path, m));
      }
      const cv::Mat ref = cv::imread(path, cv::IMREAD_UNCHANGED);
      ASSERT_EQ(ref.type(), type) << path;
      const Frame fr = ReadFrame(path);
      ASSERT_EQ(fr.image.width, m.cols);
      ASSERT_EQ(fr.image.height, m.rows);
      EXPECT_EQ(fr.bit_depth, CV_MAT_DEPTH(type) == CV_8U ? 8 : 16);
      EXPECT_EQ(fr.grey_conversion, m.channels() == 1 ? "none" : "mean_rgb") << path;
      cv::Mat grey;
      if (m.channels() == 1) {
        ref.convertTo(grey, CV_32S);
      } else {
        std::vector<cv::Mat> planes;
        cv::split(ref, planes);
        cv::Mat sum;
        cv::add(planes[0], planes[1], sum, cv::noArray(), CV_32S);
        cv::add(sum, planes[2], sum, cv::noArray(), CV_32S);
        sum.convertTo(grey, CV_MAT_DEPTH(type), 1.0 / 3.0);  // rounded to nearest
        grey.convertTo(grey, CV_32S);
      }
      for (int y = 0; y < m.rows; ++y)
        for (int x = 0; x < m.cols; ++x)
          ASSERT_EQ(fr.image.at(x, y), grey.at<int>(y, x)) << path << " " << x << "," << y;
    }
  }
  // A truncated TIFF is an error naming the file, nothing on stderr but the one line.
  std::ifstream in(dir + "/f1.tiff", std::ios::binary);
  const std::string tiff((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(dir + "/cut.tiff", std::ios::binary) << tiff.substr(0, 200);
  EXPECT_THAT(ErrorOf(dir + "/cut.tiff"), ::testing::HasSubstr("cut.tiff"));
}

// JPEG and BMP (libturbojpeg, loaded on first use): OpenCV's codecs (the system's libjpeg-turbo, its
// default accurate integer IDCT) are the reference: grey read as it is, colour as the rounded mean of
// R, G, B; BMP is lossless, so the pixels written come back. A truncated JPEG (a decoder warning) and
// a BMP larger than the limit are errors naming the file.
TEST(RasterCodec, JpegAndBmpMatchOpenCv) {
  const std::string dir = testing::TempDir("codec_jpeg");
  for (int type : {CV_8UC1, CV_8UC3}) {
    cv::Mat m(61, 83, type);
    cv::randu(m, 0, 256);
    cv::GaussianBlur(m, m, cv::Size(5, 5), 1.5);  // a star-like smooth field: JPEG's usual content
    for (const std::string ext : {".jpg", ".bmp"}) {
      const std::string path = dir + "/f" + std::to_string(type) + ext;
      ASSERT_TRUE(cv::imwrite(path, m, {cv::IMWRITE_JPEG_QUALITY, 85}));
      const cv::Mat ref = cv::imread(path, cv::IMREAD_UNCHANGED);
      ASSERT_EQ(ref.type(), type) << path;
      if (ext == ".bmp") {
        EXPECT_EQ(cv::norm(ref, m, cv::NORM_INF), 0);  // lossless
      }
      const Frame fr = ReadFrame(path);
      ASSERT_EQ(fr.image.width, m.cols);
      ASSERT_EQ(fr.image.height, m.rows);
      EXPECT_EQ(fr.bit_depth, 8);
      EXPECT_EQ(fr.saturation_adu, 255);
      EXPECT_EQ(fr.grey_conversion, m.channels() == 1 ? "none" : "mean_rgb") << path;
      for (int y = 0; y < m.rows; ++y) {
        for (int x = 0; x < m.cols; ++x) {
          int want = 0;
          if (m.channels() == 1) {
            want = ref.at<uchar>(y, x);
          } else {
            const cv::Vec3b p = ref.at<cv::Vec3b>(y, x);
            want = (p[0] + p[1] + p[2] + 1) / 3;
          }
          ASSERT_EQ(fr.image.at(x, y), want) << path << " " << x << "," << y;
        }
      }
    }
  }
  std::ifstream in(dir + "/f" + std::to_string(CV_8UC3) + ".jpg", std::ios::binary);
  const std::string jpg((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(dir + "/cut.jpg", std::ios::binary) << jpg.substr(0, jpg.size() / 2);
  EXPECT_THAT(ErrorOf(dir + "/cut.jpg"), ::testing::HasSubstr("cut.jpg: cannot decode image"));
  std::ofstream(dir + "/head.jpg", std::ios::binary) << jpg.substr(0, 40);
  EXPECT_THAT(ErrorOf(dir + "/head.jpg"), ::testing::HasSubstr("head.jpg: cannot decode image"));
  // A BMP header declaring 70000 x 10 px: refused from the header, before any pixel is read.
  std::string bmp(54, '\0');
  bmp[0] = 'B', bmp[1] = 'M', bmp[14] = 40;
  const uint32_t w = 70000, h = 10;
  for (int k = 0; k < 4; ++k) bmp[18 + k] = static_cast<char>(w >> (8 * k)), bmp[22 + k] = static_cast<char>(h >> (8 * k));
  std::ofstream(dir + "/wide.bmp", std::ios::binary) << bmp;
  EXPECT_THAT(ErrorOf(dir + "/wide.bmp"), ::testing::HasSubstr("wide.bmp: "));
  EXPECT_THAT(ErrorOf(dir + "/wide.bmp"), ::testing::HasSubstr("70000"));
}

}  // namespace
}  // namespace ssiu
