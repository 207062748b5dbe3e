// Internal to core: PNG, TIFF, JPEG and BMP without OpenCV's codec chain. OpenCV's imgcodecs pulls in GDAL,
// GDCM, OpenEXR and ~120 other shared libraries that cost ~50 ms of CPU at every start of `ssiu`
// (docs/results.md, issue 17 item 2); ssiu only needs a few formats, so it calls libpng, libtiff,
// libturbojpeg and libdeflate directly. The common grey PNG keeps its own fast decoder (png_decode.h).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ssiu {

// Interleaved samples as a decoder hands them over: channels 1-4 (grey, grey+alpha, RGB, RGBA, in
// that order), depth 8 or 16 (8-bit samples stored in uint16_t too).
struct RasterSamples {
  int width = 0, height = 0, channels = 0, depth = 0;
  std::vector<uint16_t> samples;  // row-major, width * channels per row
};

// Any PNG libpng reads, as OpenCV's IMREAD_UNCHANGED gave it: palette -> RGB (RGBA with a tRNS
// chunk), grey+alpha -> RGBA, 1/2/4-bit grey scaled to 8 bits, a grey tRNS ignored, interlacing
// undone. InputError naming `path` (with libpng's reason) for a corrupt or truncated file, or one
// wider or taller than max_side_px (checked before the pixels are allocated).
RasterSamples DecodePngLibpng(const std::vector<uint8_t>& bytes, const std::string& path, int64_t max_side_px);

// True when `bytes` start with a TIFF header (II*\0 or MM\0*).
bool IsTiff(const std::vector<uint8_t>& bytes);
// A TIFF's first image: 8/16-bit unsigned grey, grey+alpha, RGB or RGBA, in strips or tiles, any
// compression libtiff knows; other 8-bit kinds (palette, YCbCr, CMYK, 1-4 bit) through libtiff's
// RGBA reader. InputError naming `path` for a corrupt file, an unsupported kind, or a side longer
// than max_side_px (checked before the pixels are allocated).
RasterSamples DecodeTiff(const std::string& path, int64_t max_side_px);

// True when `bytes` start with a JPEG SOI marker and the first marker's prefix (FF D8 FF).
bool IsJpeg(const std::vector<uint8_t>& bytes);
// True when `bytes` start with a Windows BMP file header ("BM").
bool IsBmp(const std::vector<uint8_t>& bytes);
// A JPEG (baseline or progressive, grey or colour) decoded by libjpeg-turbo's TurboJPEG API, loaded on
// first use like libtiff: grey as one 8-bit channel, colour as RGB. A warning of the decoder (a
// truncated or damaged stream) is an error. InputError naming `path` for a corrupt file, a side longer
// than max_side_px (from the header, before the pixels are allocated), or a build without TurboJPEG.
RasterSamples DecodeJpeg(const std::vector<uint8_t>& bytes, const std::string& path, int64_t max_side_px);
// A BMP (8-bit with a grey palette as one channel; 8-bit palette, 24- and 32-bit colour as RGB) read
// from `path` by TurboJPEG's loader; `header` holds the file's first bytes (its size is checked from
// them before the loader allocates the pixels); the same errors.
RasterSamples DecodeBmp(const std::vector<uint8_t>& header, const std::string& path, int64_t max_side_px);

// A PNG file's bytes: `samples` row-major interleaved, channels 1-4 (grey, grey+alpha, RGB, RGBA),
// depth 8 (uint8_t samples) or 16 (uint16_t samples, host order); each row filtered with the
// PNG filter that minimises the sum of absolute differences (the libpng heuristic), deflated
// with libdeflate at `level` (1-12).
std::string EncodePng(const void* samples, int width, int height, int channels, int depth, int level = 6);

}  // namespace ssiu
