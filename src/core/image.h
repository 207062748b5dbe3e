// Frames: a non-owning view for the stages, an owning 16-bit image, and file I/O at the edge
// (libpng/libtiff for PNG/TIFF, cfitsio for FITS). Pixel (0,0) is the centre of the top-left pixel; for FITS
// the first stored row is y = 0 (so FITS pixel (i, j) is our (i - 1, j - 1)).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace ssiu {

// Non-owning view of a 16-bit single-channel image (AprilTag's image_u8 idea). stride in pixels.
struct ImageView {
  int width = 0;
  int height = 0;
  std::ptrdiff_t stride = 0;
  const uint16_t* data = nullptr;
  uint16_t at(int x, int y) const { return data[static_cast<std::ptrdiff_t>(y) * stride + x]; }
  const uint16_t* row(int y) const { return data + static_cast<std::ptrdiff_t>(y) * stride; }
};

struct Image16 {
  int width = 0;
  int height = 0;
  std::vector<uint16_t> pixels;  // row-major, stride == width

  Image16() = default;
  Image16(int w, int h, uint16_t fill = 0)
      : width(w), height(h), pixels(static_cast<size_t>(w) * static_cast<size_t>(h), fill) {}
  uint16_t& at(int x, int y) { return pixels[static_cast<size_t>(y) * width + x]; }
  uint16_t at(int x, int y) const { return pixels[static_cast<size_t>(y) * width + x]; }
  ImageView view() const { return {width, height, width, pixels.data()}; }
};

// A frame read from a file. Pixel values are stored as 16-bit counts; original value =
// stored * value_scale + value_offset (1 and 0 except for FITS data outside 0..65535).
struct Frame {
  std::string file;
  Image16 image;
  int bit_depth = 16;             // 8 or 16 (FITS: 16 after conversion)
  double saturation_adu = 65535;  // full-scale value in stored counts
  double value_scale = 1.0;
  double value_offset = 0.0;
  std::string grey_conversion = "none";  // how colour was reduced to grey, e.g. "mean_rgb"
  std::string date_obs;                  // FITS DATE-OBS as written (the frame's UTC time); "" when absent
};

// Reads PNG/TIFF (8/16-bit; grey, or RGB/RGBA reduced to grey by the mean of R, G, B) or FITS
// (primary HDU, BITPIX 8, 16, 32, -32). Throws InputError naming the file for a missing, empty,
// corrupt, truncated, wrongly typed, constant (all-zero / all-saturated) or mostly saturated image.
Frame ReadFrame(const std::string& path);

// Limits checked before any pixel is allocated: an 8 MB PNG can declare 65536 x 65536 pixels
// (8.6 GB). The defaults are sized for star trackers (the largest sensors flown are near 4k x 4k);
// $SSIU_MAX_IMAGE_SIDE_PX and $SSIU_MAX_INPUT_MB override them (docs/conventions.md).
struct ImageLimits {
  int64_t max_side_px = 16384;                // width and height each
  int64_t max_file_bytes = int64_t{2} << 30;  // 2 GiB: a 16k x 16k 64-bit FITS frame
  static ImageLimits FromEnvironment();       // the defaults, overridden by the variables above
};
// ReadFrame with explicit limits; InputError naming the file and the limit when one is exceeded.
Frame ReadFrame(const std::string& path, const ImageLimits& limits);
// The width and height an image file declares in its header (PNG IHDR, TIFF first IFD, FITS NAXISn),
// read without decoding; false when the format is not one of these or the header is unreadable.
bool DeclaredImageSize(const std::string& path, int64_t* width, int64_t* height);

// Rejects images that carry no usable signal; `file` names the source in the message.
void CheckFrameContent(const Frame& frame);

// frame - dark + pedestal (dark or median frame of the same camera), clamped to 0..65534; pixels
// saturated in `frame` become 65535 and saturation_adu becomes 65535, so they stay flagged.
// InputError naming the dark file when the sizes differ.
Frame SubtractDark(const Frame& frame, const Frame& dark, double pedestal_adu = 100.0);

// PNG outputs, written atomically (core/output.h); InputError naming the file when it cannot be
// written or its name has an extension other than .png.
// Pixels: `channels` (1-4, OpenCV's order: grey, BGR, BGRA) of `depth` bits (8 or 16, native
// order) each, rows stride_bytes apart (core/image_cv.h takes a cv::Mat).
void WritePng(const std::string& path, const void* pixels, int width, int height, int channels, int depth,
              size_t stride_bytes);
// The PNG file of such an image, deflated at `level` (libdeflate, 1-12); std::invalid_argument for
// another type. No OpenCV codec involved.
std::string PngBytes(const void* pixels, int width, int height, int channels, int depth, size_t stride_bytes,
                     int level = 6);
// InputError unless `path` names a PNG (extension .png, or none): checked before work is done.
void CheckPngOutputName(const std::string& path);
void WritePng16(const std::string& path, const Image16& image);
// Binary 16-bit PGM (Netpbm P5, maxval 65535, big-endian samples): a frame any C program reads with
// one read() (examples/flight).
void WritePgm16(const std::string& path, const Image16& image);
void WritePng8(const std::string& path, int width, int height, const std::vector<uint8_t>& pixels);
// 16-bit FITS (BITPIX 16 with BZERO 32768), first stored row = y 0.
void WriteFits16(const std::string& path, const Image16& image);

}  // namespace ssiu
