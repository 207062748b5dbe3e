#include "core/raster_codec.h"

#include <libdeflate.h>
#include <png.h>
#include <tiffio.h>
#ifdef SSIU_TURBOJPEG_SONAME
#include <turbojpeg.h>
#endif

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <stdexcept>

#include "core/error.h"
#include "core/lazy_library.h"

namespace ssiu {
namespace {

const char kCannotDecode[] = "cannot decode image (corrupt, truncated or not PNG/TIFF/FITS/JPEG/BMP)";

InputError Undecodable(const std::string& path, const std::string& why) {
  return InputError(path, std::string(kCannotDecode) + (why.empty() ? "" : ": " + why));
}

bool LittleEndianHost() {
  const uint16_t one = 1;
  uint8_t first = 0;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

// ---- libpng (libpng manual, "Reading PNG files"; errors through setjmp/longjmp) ----

struct PngSource {
  const uint8_t* data;
  size_t size;
  size_t pos;
};

void PngRead(png_structp png, png_bytep out, size_t n) {
  auto* s = static_cast<PngSource*>(png_get_io_ptr(png));
  if (n > s->size - s->pos) png_error(png, "file truncated");
  std::memcpy(out, s->data + s->pos, n);
  s->pos += n;
}

struct PngMessage {
  char text[200] = {0};
};

void PngError(png_structp png, png_const_charp msg) {
  std::snprintf(static_cast<PngMessage*>(png_get_error_ptr(png))->text, sizeof(PngMessage::text), "%s", msg);
  png_longjmp(png, 1);
}

void PngWarning(png_structp, png_const_charp) {}  // libpng would print them on stderr

// Every libpng call that can fail, in a frame with no object that has a destructor (longjmp would
// skip it); the buffers belong to the caller. The transforms are OpenCV's for IMREAD_UNCHANGED.
bool ReadPng(png_structp png, png_infop info, PngSource* src, int64_t max_side_px, std::vector<uint8_t>* bytes,
             std::vector<png_bytep>* rows, RasterSamples* out) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_read_fn(png, src, PngRead);
  png_read_info(png, info);
  png_uint_32 w = 0, h = 0;
  int depth = 0, color = 0;
  png_get_IHDR(png, info, &w, &h, &depth, &color, nullptr, nullptr, nullptr);
  if (w > max_side_px || h > max_side_px) png_error(png, "image larger than the limit (SSIU_MAX_IMAGE_SIDE_PX)");
  const bool trns = png_get_valid(png, info, PNG_INFO_tRNS) != 0;
  if (color == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if ((color == PNG_COLOR_TYPE_PALETTE || color == PNG_COLOR_TYPE_RGB) && trns) png_set_tRNS_to_alpha(png);
  if (color == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if (color == PNG_COLOR_TYPE_GRAY_ALPHA) png_set_gray_to_rgb(png);
  if (depth == 16 && LittleEndianHost()) png_set_swap(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  out->width = static_cast<int>(w);
  out->height = static_cast<int>(h);
  out->channels = png_get_channels(png, info);
  out->depth = png_get_bit_depth(png, info);
  const size_t row_bytes = png_get_rowbytes(png, info);
  bytes->resize(row_bytes * h);
  rows->resize(h);
  for (png_uint_32 y = 0; y < h; ++y) (*rows)[y] = bytes->data() + row_bytes * y;
  png_read_image(png, rows->data());
  png_read_end(png, nullptr);
  return true;
}

// ---- libtiff ----

// libtiff is loaded on first use: it links libjpeg, libwebp, libzstd, liblzma, libLerc and libjbig
// (7 libraries, ~0.3 ms at every start of `ssiu`, issue 17), and most runs read no TIFF.
struct TiffApi {
  decltype(&TIFFOpenOptionsAlloc) OpenOptionsAlloc;
  decltype(&TIFFOpenOptionsSetErrorHandlerExtR) OpenOptionsSetErrorHandlerExtR;
  decltype(&TIFFOpenOptionsSetWarningHandlerExtR) OpenOptionsSetWarningHandlerExtR;
  decltype(&TIFFOpenExt) OpenExt;
  decltype(&TIFFOpenOptionsFree) OpenOptionsFree;
  decltype(&TIFFClose) Close;
  decltype(&TIFFGetField) GetField;
  decltype(&TIFFGetFieldDefaulted) GetFieldDefaulted;
  decltype(&TIFFIsTiled) IsTiled;
  decltype(&TIFFTileSize) TileSize;
  decltype(&TIFFReadTile) ReadTile;
  decltype(&TIFFScanlineSize) ScanlineSize;
  decltype(&TIFFReadScanline) ReadScanline;
  decltype(&TIFFReadRGBAImageOriented) ReadRGBAImageOriented;
};

const TiffApi& Tiff() {
  static const TiffApi api = [] {  // C++11: initialised once, thread-safe; retried if it threw
    constexpr const char* so = SSIU_LIBTIFF_SONAME;
    void* lib = internal::OpenLazyLibrary(so, "TIFF support");
    TiffApi a{};
    internal::Resolve(lib, so, "TIFFOpenOptionsAlloc", &a.OpenOptionsAlloc);
    internal::Resolve(lib, so, "TIFFOpenOptionsSetErrorHandlerExtR", &a.OpenOptionsSetErrorHandlerExtR);
    internal::Resolve(lib, so, "TIFFOpenOptionsSetWarningHandlerExtR", &a.OpenOptionsSetWarningHandlerExtR);
    internal::Resolve(lib, so, "TIFFOpenExt", &a.OpenExt);
    internal::Resolve(lib, so, "TIFFOpenOptionsFree", &a.OpenOptionsFree);
    internal::Resolve(lib, so, "TIFFClose", &a.Close);
    internal::Resolve(lib, so, "TIFFGetField", &a.GetField);
    internal::Resolve(lib, so, "TIFFGetFieldDefaulted", &a.GetFieldDefaulted);
    internal::Resolve(lib, so, "TIFFIsTiled", &a.IsTiled);
    internal::Resolve(lib, so, "TIFFTileSize", &a.TileSize);
    internal::Resolve(lib, so, "TIFFReadTile", &a.ReadTile);
    internal::Resolve(lib, so, "TIFFScanlineSize", &a.ScanlineSize);
    internal::Resolve(lib, so, "TIFFReadScanline", &a.ReadScanline);
    internal::Resolve(lib, so, "TIFFReadRGBAImageOriented", &a.ReadRGBAImageOriented);
    return a;
  }();
  return api;
}

int TiffError(TIFF*, void* user, const char* module, const char* fmt, va_list ap) {
  auto* msg = static_cast<std::string*>(user);
  if (msg->empty()) {  // the first error says what went wrong; later ones follow from it
    char buf[200];
    std::vsnprintf(buf, sizeof buf, fmt, ap);
    *msg = std::string(module ? module : "libtiff") + ": " + buf;
  }
  return 1;  // handled: nothing on stderr
}

int TiffWarning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

// Copies `n` samples of `bits` (8 or 16, host order) to `dst`.
void CopySamples(const uint8_t* src, int bits, size_t n, uint16_t* dst) {
  if (bits == 16) {
    std::memcpy(dst, src, n * 2);
  } else {
    for (size_t i = 0; i < n; ++i) dst[i] = src[i];
  }
}

// ---- libturbojpeg (JPEG, and BMP through its loader) ----

#ifdef SSIU_TURBOJPEG_SONAME
// Loaded on first use as libtiff is: most runs read no JPEG.
struct TurboJpegApi {
  decltype(&tjInitDecompress) InitDecompress;
  decltype(&tjDecompressHeader3) DecompressHeader3;
  decltype(&tjDecompress2) Decompress2;
  decltype(&tjDestroy) Destroy;
  decltype(&tjGetErrorStr2) GetErrorStr2;
  decltype(&tjLoadImage) LoadImage;
  decltype(&tjFree) Free;
};

const TurboJpegApi& TurboJpeg() {
  static const TurboJpegApi api = [] {
    constexpr const char* so = SSIU_TURBOJPEG_SONAME;
    void* lib = internal::OpenLazyLibrary(so, "JPEG/BMP support");
    TurboJpegApi a{};
    internal::Resolve(lib, so, "tjInitDecompress", &a.InitDecompress);
    internal::Resolve(lib, so, "tjDecompressHeader3", &a.DecompressHeader3);
    internal::Resolve(lib, so, "tjDecompress2", &a.Decompress2);
    internal::Resolve(lib, so, "tjDestroy", &a.Destroy);
    internal::Resolve(lib, so, "tjGetErrorStr2", &a.GetErrorStr2);
    internal::Resolve(lib, so, "tjLoadImage", &a.LoadImage);
    internal::Resolve(lib, so, "tjFree", &a.Free);
    return a;
  }();
  return api;
}

InputError TooLarge(const std::string& path, int64_t w, int64_t h, int64_t max_side_px) {
  return InputError(path, "image of " + std::to_string(w) + " x " + std::to_string(h) + " px, more than the limit of " +
                              std::to_string(max_side_px) + " per side");
}
#endif

// ---- PNG writing (ISO/IEC 15948: 5 chunks, 9 filters, 11.2.2 IHDR) ----

void PutBe32(std::string* s, uint32_t v) {
  for (int b = 3; b >= 0; --b) s->push_back(static_cast<char>((v >> (8 * b)) & 0xff));
}

void PutChunk(std::string* png, const char* type, const std::string& data) {
  PutBe32(png, static_cast<uint32_t>(data.size()));
  const std::string body = std::string(type, 4) + data;
  *png += body;
  PutBe32(png, libdeflate_crc32(0, body.data(), body.size()));
}

// Row `c` filtered with `type` against the previous row `p` into `out`; returns the sum of the
// filtered bytes as signed values (the libpng heuristic for choosing a filter).
uint64_t Filter(int type, const uint8_t* c, const uint8_t* p, size_t n, size_t bpp, uint8_t* out) {
  uint64_t sum = 0;
  for (size_t x = 0; x < n; ++x) {
    const int a = x >= bpp ? c[x - bpp] : 0, up = p[x], ul = x >= bpp ? p[x - bpp] : 0;
    int pred = 0;
    switch (type) {
      case 1:
        pred = a;
        break;
      case 2:
        pred = up;
        break;
      case 3:
        pred = (a + up) >> 1;
        break;
      case 4: {
        const int pa = std::abs(up - ul), pb = std::abs(a - ul), pc = std::abs(a + up - 2 * ul);
        pred = (pa <= pb && pa <= pc) ? a : (pb <= pc ? up : ul);
        break;
      }
      default:
        break;
    }
    out[x] = static_cast<uint8_t>(c[x] - pred);
    sum += static_cast<uint64_t>(std::abs(static_cast<int8_t>(out[x])));
  }
  return sum;
}

}  // namespace

RasterSamples DecodePngLibpng(const std::vector<uint8_t>& bytes, const std::string& path, int64_t max_side_px) {
  PngMessage msg;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &msg, PngError, PngWarning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!info) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    throw InputError(path, "out of memory decoding PNG");
  }
  PngSource src{bytes.data(), bytes.size(), 0};
  std::vector<uint8_t> raw;
  std::vector<png_bytep> rows;
  RasterSamples out;
  const bool ok = ReadPng(png, info, &src, max_side_px, &raw, &rows, &out);
  png_destroy_read_struct(&png, &info, nullptr);
  if (!ok) throw Undecodable(path, std::string("libpng: ") + msg.text);
  if (out.depth != 8 && out.depth != 16) throw Undecodable(path, "unexpected bit depth after expansion");
  const size_t n = static_cast<size_t>(out.width) * out.height * out.channels;
  out.samples.resize(n);
  CopySamples(raw.data(), out.depth, n, out.samples.data());
  return out;
}

bool IsTiff(const std::vector<uint8_t>& b) {
  return b.size() >= 4 && ((b[0] == 'I' && b[1] == 'I' && b[2] == 42 && b[3] == 0) ||
                           (b[0] == 'M' && b[1] == 'M' && b[2] == 0 && b[3] == 42));
}

RasterSamples DecodeTiff(const std::string& path, int64_t max_side_px) {
  const TiffApi& tiff = Tiff();
  std::string err;
  TIFFOpenOptions* opts = tiff.OpenOptionsAlloc();
  if (!opts) throw InputError(path, "out of memory decoding TIFF");
  tiff.OpenOptionsSetErrorHandlerExtR(opts, TiffError, &err);
  tiff.OpenOptionsSetWarningHandlerExtR(opts, TiffWarning, nullptr);
  TIFF* t = tiff.OpenExt(path.c_str(), "r", opts);
  tiff.OpenOptionsFree(opts);
  if (!t) throw Undecodable(path, err);
  std::unique_ptr<TIFF, void (*)(TIFF*)> close(t, tiff.Close);
  uint32_t w = 0, h = 0;
  uint16_t bits = 1, spp = 1, planar = PLANARCONFIG_CONTIG, format = SAMPLEFORMAT_UINT, photo = PHOTOMETRIC_MINISBLACK;
  tiff.GetField(t, TIFFTAG_IMAGEWIDTH, &w);
  tiff.GetField(t, TIFFTAG_IMAGELENGTH, &h);
  tiff.GetFieldDefaulted(t, TIFFTAG_BITSPERSAMPLE, &bits);
  tiff.GetFieldDefaulted(t, TIFFTAG_SAMPLESPERPIXEL, &spp);
  tiff.GetFieldDefaulted(t, TIFFTAG_PLANARCONFIG, &planar);
  tiff.GetFieldDefaulted(t, TIFFTAG_SAMPLEFORMAT, &format);
  tiff.GetField(t, TIFFTAG_PHOTOMETRIC, &photo);
  if (w == 0 || h == 0) throw InputError(path, "image has zero size");
  if (w > max_side_px || h > max_side_px) {
    throw InputError(path, "image is larger than the limit of " + std::to_string(max_side_px) +
                               " px per side (SSIU_MAX_IMAGE_SIDE_PX)");
  }
  RasterSamples out;
  out.width = static_cast<int>(w);
  out.height = static_cast<int>(h);
  const bool plain = (bits == 8 || bits == 16) && format == SAMPLEFORMAT_UINT && planar == PLANARCONFIG_CONTIG &&
                     spp >= 1 && spp <= 4 &&
                     (photo == PHOTOMETRIC_MINISBLACK || (photo == PHOTOMETRIC_RGB && spp >= 3));
  if (plain) {
    out.channels = spp;
    out.depth = bits;
    const size_t row_samples = static_cast<size_t>(w) * spp;
    out.samples.resize(row_samples * h);
    if (tiff.IsTiled(t)) {
      uint32_t tw = 0, th = 0;
      tiff.GetField(t, TIFFTAG_TILEWIDTH, &tw);
      tiff.GetField(t, TIFFTAG_TILELENGTH, &th);
      if (tw == 0 || th == 0) throw Undecodable(path, "tile size is zero");
      std::vector<uint8_t> tile(static_cast<size_t>(tiff.TileSize(t)));
      const size_t tile_row = static_cast<size_t>(tw) * spp;
      if (tile.size() < tile_row * th * (bits / 8))
        throw Undecodable(path, "tile size does not match the tile's pixels");
      for (uint32_t ty = 0; ty < h; ty += th)
        for (uint32_t tx = 0; tx < w; tx += tw) {
          if (tiff.ReadTile(t, tile.data(), tx, ty, 0, 0) < 0) throw Undecodable(path, err);
          const uint32_t cols = std::min(tw, w - tx), rows = std::min(th, h - ty);
          for (uint32_t y = 0; y < rows; ++y) {
            CopySamples(tile.data() + y * tile_row * (bits / 8), bits, static_cast<size_t>(cols) * spp,
                        out.samples.data() + (ty + y) * row_samples + static_cast<size_t>(tx) * spp);
          }
        }
    } else {
      std::vector<uint8_t> line(static_cast<size_t>(tiff.ScanlineSize(t)));
      if (line.size() < row_samples * (bits / 8)) throw Undecodable(path, "scanline size does not match the width");
      for (uint32_t y = 0; y < h; ++y) {
        if (tiff.ReadScanline(t, line.data(), y, 0) < 0) throw Undecodable(path, err);
        CopySamples(line.data(), bits, row_samples, out.samples.data() + y * row_samples);
      }
    }
    return out;
  }
  if (bits > 8 || format != SAMPLEFORMAT_UINT) {
    throw InputError(path, "unsupported pixel type (only 8- or 16-bit unsigned images are read)");
  }
  // Palette, YCbCr, CMYK, 1-4 bit, separate planes: libtiff's RGBA reader (8-bit RGBA).
  std::vector<uint32_t> rgba(static_cast<size_t>(w) * h);
  if (!tiff.ReadRGBAImageOriented(t, w, h, rgba.data(), ORIENTATION_TOPLEFT, 0)) throw Undecodable(path, err);
  out.channels = 4;
  out.depth = 8;
  out.samples.resize(rgba.size() * 4);
  for (size_t i = 0; i < rgba.size(); ++i) {
    out.samples[4 * i] = static_cast<uint16_t>(TIFFGetR(rgba[i]));
    out.samples[4 * i + 1] = static_cast<uint16_t>(TIFFGetG(rgba[i]));
    out.samples[4 * i + 2] = static_cast<uint16_t>(TIFFGetB(rgba[i]));
    out.samples[4 * i + 3] = static_cast<uint16_t>(TIFFGetA(rgba[i]));
  }
  return out;
}

std::string EncodePng(const void* samples, int width, int height, int channels, int depth, int level) {
  if (width <= 0 || height <= 0 || channels < 1 || channels > 4 || (depth != 8 && depth != 16)) {
    throw std::invalid_argument("EncodePng: bad image shape");
  }
  const size_t bpp = static_cast<size_t>(channels) * (depth / 8);
  const size_t n = static_cast<size_t>(width) * bpp;
  const size_t row_samples = static_cast<size_t>(width) * channels;
  std::vector<uint8_t> raw((n + 1) * height), prev(n, 0), cur(n), trial(n), best(n);
  for (int y = 0; y < height; ++y) {
    if (depth == 8) {
      std::memcpy(cur.data(), static_cast<const uint8_t*>(samples) + y * row_samples, n);
    } else {
      const uint16_t* s = static_cast<const uint16_t*>(samples) + y * row_samples;
      for (size_t i = 0; i < row_samples; ++i) {  // PNG samples are big-endian
        cur[2 * i] = static_cast<uint8_t>(s[i] >> 8);
        cur[2 * i + 1] = static_cast<uint8_t>(s[i] & 0xff);
      }
    }
    int best_type = 0;
    uint64_t best_sum = Filter(0, cur.data(), prev.data(), n, bpp, best.data());
    for (int type = 1; type <= 4; ++type) {
      const uint64_t sum = Filter(type, cur.data(), prev.data(), n, bpp, trial.data());
      if (sum < best_sum) {
        best_sum = sum;
        best_type = type;
        best.swap(trial);
      }
    }
    uint8_t* row = raw.data() + static_cast<size_t>(y) * (n + 1);
    row[0] = static_cast<uint8_t>(best_type);
    std::memcpy(row + 1, best.data(), n);
    prev.swap(cur);
  }
  libdeflate_compressor* c = libdeflate_alloc_compressor(level);
  if (!c) throw std::bad_alloc();
  std::string z(libdeflate_zlib_compress_bound(c, raw.size()), '\0');
  z.resize(libdeflate_zlib_compress(c, raw.data(), raw.size(), z.data(), z.size()));
  libdeflate_free_compressor(c);
  if (z.empty()) throw std::runtime_error("EncodePng: deflate failed");

  static const int kColourType[5] = {0, 0, 4, 2, 6};  // grey, grey+alpha, RGB, RGBA
  std::string ihdr;
  PutBe32(&ihdr, static_cast<uint32_t>(width));
  PutBe32(&ihdr, static_cast<uint32_t>(height));
  ihdr += {static_cast<char>(depth), static_cast<char>(kColourType[channels]), 0, 0, 0};
  std::string png("\x89PNG\r\n\x1a\n", 8);
  PutChunk(&png, "IHDR", ihdr);
  PutChunk(&png, "IDAT", z);
  PutChunk(&png, "IEND", "");
  return png;
}

bool IsJpeg(const std::vector<uint8_t>& b) { return b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF; }

bool IsBmp(const std::vector<uint8_t>& b) { return b.size() >= 2 && b[0] == 'B' && b[1] == 'M'; }

#ifdef SSIU_TURBOJPEG_SONAME
RasterSamples DecodeJpeg(const std::vector<uint8_t>& bytes, const std::string& path, int64_t max_side_px) {
  const TurboJpegApi& tj = TurboJpeg();
  tjhandle h = tj.InitDecompress();
  if (!h) throw InputError(path, "out of memory decoding JPEG");
  struct Closer {
    const TurboJpegApi& tj;
    tjhandle h;
    ~Closer() { tj.Destroy(h); }
  } closer{tj, h};
  int w = 0, ht = 0, subsamp = 0, colourspace = 0;
  const auto* data = bytes.data();
  const auto size = static_cast<unsigned long>(bytes.size());
  if (tj.DecompressHeader3(h, data, size, &w, &ht, &subsamp, &colourspace) != 0) {
    throw Undecodable(path, std::string("libjpeg-turbo: ") + tj.GetErrorStr2(h));
  }
  if (w <= 0 || ht <= 0) throw Undecodable(path, "JPEG of zero size");
  if (w > max_side_px || ht > max_side_px) throw TooLarge(path, w, ht, max_side_px);
  RasterSamples out;
  out.width = w, out.height = ht, out.depth = 8;
  out.channels = colourspace == TJCS_GRAY ? 1 : 3;
  std::vector<uint8_t> px(static_cast<size_t>(w) * ht * out.channels);
  // A warning (a truncated or damaged stream, filled with grey by libjpeg) is an error here.
  if (tj.Decompress2(h, data, size, px.data(), w, 0, ht, out.channels == 1 ? TJPF_GRAY : TJPF_RGB,
                     TJFLAG_STOPONWARNING | TJFLAG_ACCURATEDCT) != 0) {
    throw Undecodable(path, std::string("libjpeg-turbo: ") + tj.GetErrorStr2(h));
  }
  out.samples.assign(px.begin(), px.end());
  return out;
}

RasterSamples DecodeBmp(const std::vector<uint8_t>& header, const std::string& path, int64_t max_side_px) {
  // BITMAPINFOHEADER (or larger): width and height at bytes 18 and 22, little-endian, height < 0 for a
  // top-down image; checked before the loader allocates the pixels.
  if (header.size() < 26) throw Undecodable(path, "BMP header truncated");
  auto le32 = [&](int i) {
    return static_cast<int32_t>(uint32_t(header[i]) | uint32_t(header[i + 1]) << 8 | uint32_t(header[i + 2]) << 16 |
                                uint32_t(header[i + 3]) << 24);
  };
  const int64_t w = le32(18), ht = std::abs(static_cast<int64_t>(le32(22)));
  if (w > max_side_px || ht > max_side_px) throw TooLarge(path, w, ht, max_side_px);
  const TurboJpegApi& tj = TurboJpeg();
  int width = 0, height = 0, format = TJPF_UNKNOWN;
  unsigned char* px = tj.LoadImage(path.c_str(), &width, 1, &height, &format, 0);
  if (!px) throw Undecodable(path, std::string("libjpeg-turbo: ") + tj.GetErrorStr2(nullptr));
  struct Freer {
    const TurboJpegApi& tj;
    unsigned char* p;
    ~Freer() { tj.Free(p); }
  } freer{tj, px};
  if (width <= 0 || height <= 0 || width > max_side_px || height > max_side_px) {
    throw TooLarge(path, width, height, max_side_px);
  }
  RasterSamples out;
  out.width = width, out.height = height, out.depth = 8;
  const size_t n = static_cast<size_t>(width) * height;
  if (format == TJPF_GRAY) {
    out.channels = 1;
    out.samples.assign(px, px + n);
    return out;
  }
  if (format < 0 || format >= TJ_NUMPF || tjRedOffset[format] < 0) throw Undecodable(path, "BMP pixel format");
  out.channels = 3;
  out.samples.resize(3 * n);
  const int step = tjPixelSize[format], r = tjRedOffset[format], g = tjGreenOffset[format], b = tjBlueOffset[format];
  for (size_t i = 0; i < n; ++i) {
    const unsigned char* p = px + i * step;
    out.samples[3 * i] = p[r], out.samples[3 * i + 1] = p[g], out.samples[3 * i + 2] = p[b];
  }
  return out;
}
#else
RasterSamples DecodeJpeg(const std::vector<uint8_t>&, const std::string& path, int64_t) {
  throw InputError(path, "JPEG support not built (libturbojpeg0-dev was missing when ssiu was configured)");
}
RasterSamples DecodeBmp(const std::vector<uint8_t>&, const std::string& path, int64_t) {
  throw InputError(path, "BMP support not built (libturbojpeg0-dev was missing when ssiu was configured)");
}
#endif

}  // namespace ssiu
