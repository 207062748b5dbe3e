#include "core/png_decode.h"

#include <libdeflate.h>

#include <cstdlib>
#include <cstring>
#include <memory>

#include "core/error.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace ssiu {
namespace {

// PNG structure and filters: ISO/IEC 15948 (PNG 2nd ed.), sections 5 (chunks), 9 (filters),
// 11.2.2 (IHDR).
uint32_t Be32(const uint8_t* p) {
  return (uint32_t(p[0]) << 24) | (uint32_t(p[1]) << 16) | (uint32_t(p[2]) << 8) | uint32_t(p[3]);
}

[[noreturn]] void Corrupt(const std::string& path, const std::string& what) {
  throw InputError(path, "cannot decode PNG: " + what);
}

// Sub filter, in place on `c` (already holding the filtered bytes): c[x] += c[x - bpp].
void UnSub(uint8_t* c, size_t n, int bpp) {
  size_t x = static_cast<size_t>(bpp);
#if defined(__SSE2__)
  // Prefix sum of bpp-byte lanes in 16-byte blocks (log-step shifts), plus the carry of the
  // previous block's last pixel broadcast to every lane.
  if (bpp == 2 && n >= 18) {
    __m128i carry = _mm_setzero_si128();
    carry = _mm_insert_epi16(carry, c[0] | (c[1] << 8), 7);
    carry = _mm_shufflehi_epi16(carry, 0xFF);
    carry = _mm_unpackhi_epi64(carry, carry);
    for (; x + 16 <= n; x += 16) {
      __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c + x));
      v = _mm_add_epi8(v, _mm_slli_si128(v, 2));
      v = _mm_add_epi8(v, _mm_slli_si128(v, 4));
      v = _mm_add_epi8(v, _mm_slli_si128(v, 8));
      v = _mm_add_epi8(v, carry);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(c + x), v);
      const __m128i t = _mm_shufflehi_epi16(v, 0xFF);
      carry = _mm_unpackhi_epi64(t, t);
    }
  } else if (bpp == 1 && n >= 17) {
    for (; x + 16 <= n; x += 16) {
      __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c + x));
      v = _mm_add_epi8(v, _mm_slli_si128(v, 1));
      v = _mm_add_epi8(v, _mm_slli_si128(v, 2));
      v = _mm_add_epi8(v, _mm_slli_si128(v, 4));
      v = _mm_add_epi8(v, _mm_slli_si128(v, 8));
      v = _mm_add_epi8(v, _mm_set1_epi8(static_cast<char>(c[x - 1])));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(c + x), v);
    }
  }
#endif
  for (; x < n; ++x) c[x] = static_cast<uint8_t>(c[x] + c[x - bpp]);
}

// Reverses row filter `type` in place on `c` (n bytes) given the previous unfiltered row `p`.
bool Unfilter(int type, uint8_t* c, const uint8_t* p, size_t n, int bpp) {
  const size_t b = static_cast<size_t>(bpp);
  switch (type) {
    case 0:
      return true;
    case 1:
      UnSub(c, n, bpp);
      return true;
    case 2:
      for (size_t x = 0; x < n; ++x) c[x] = static_cast<uint8_t>(c[x] + p[x]);
      return true;
    case 3:
      for (size_t x = 0; x < b; ++x) c[x] = static_cast<uint8_t>(c[x] + (p[x] >> 1));
      for (size_t x = b; x < n; ++x) c[x] = static_cast<uint8_t>(c[x] + ((c[x - b] + p[x]) >> 1));
      return true;
    case 4:
      for (size_t x = 0; x < b; ++x) c[x] = static_cast<uint8_t>(c[x] + p[x]);
      for (size_t x = b; x < n; ++x) {
        const int a = c[x - b], up = p[x], ul = p[x - b];
        const int pa = std::abs(up - ul), pb = std::abs(a - ul), pc = std::abs(a + up - 2 * ul);
        c[x] = static_cast<uint8_t>(c[x] + ((pa <= pb && pa <= pc) ? a : (pb <= pc ? up : ul)));
      }
      return true;
    default:
      return false;
  }
}

// Big-endian 16-bit samples to host order.
void StoreBe16(const uint8_t* c, uint16_t* dst, size_t w) {
  size_t x = 0;
#if defined(__SSE2__)
  for (; x + 8 <= w; x += 8) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c + 2 * x));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + x), _mm_or_si128(_mm_slli_epi16(v, 8), _mm_srli_epi16(v, 8)));
  }
#endif
  for (; x < w; ++x) dst[x] = static_cast<uint16_t>((c[2 * x] << 8) | c[2 * x + 1]);
}

// What the chunk walk finds: the image header and the IDAT payload, packed into one zlib stream.
struct PngLayout {
  uint32_t w = 0, h = 0;
  int depth = 0;
  size_t idat_begin = 0, idat_end = 0;  // packed IDAT payload [begin, end) of the file's bytes
};

// Walks the chunks (checking the critical ones' CRC) and packs the IDAT payloads in place into one
// zlib stream (libdeflate needs it contiguous). False: a PNG this decoder leaves to libpng (colour,
// palette, alpha, interlaced, sub-byte depths, transparency).
bool ReadChunks(uint8_t* b, size_t size, const std::string& path, PngLayout* png) {
  uint32_t& w = png->w;
  uint32_t& h = png->h;
  int& depth = png->depth;
  bool idat_seen = false, idat_closed = false, iend = false;
  for (size_t pos = 8; !iend;) {
    if (pos + 12 > size) Corrupt(path, "file truncated (no IEND chunk)");
    const uint32_t len = Be32(b + pos);
    const std::string type(reinterpret_cast<const char*>(b + pos + 4), 4);
    if (len > 0x7fffffffu || pos + 12 + len > size)
      Corrupt(path, "chunk '" + type + "' runs past the end of the file (truncated)");
    const uint8_t* data = b + pos + 8;
    const bool critical = (b[pos + 4] & 0x20) == 0;
    // Critical chunks must pass their CRC (as libpng requires); ancillary ones are not read.
    if (critical && libdeflate_crc32(0, b + pos + 4, len + 4) != Be32(data + len)) {
      Corrupt(path, "chunk '" + type + "' fails its CRC");
    }
    if (pos == 8) {
      if (type != "IHDR" || len != 13) Corrupt(path, "first chunk is not IHDR");
      w = Be32(data);
      h = Be32(data + 4);
      depth = data[8];
      if (w == 0 || h == 0) Corrupt(path, "IHDR width or height is zero");
      if (data[10] != 0 || data[11] != 0) Corrupt(path, "IHDR compression or filter method is not 0");
      // Colour, palette, alpha, interlaced or sub-byte depths: libpng (raster_codec.h).
      if (data[9] != 0 || (depth != 8 && depth != 16) || data[12] != 0) return false;
      if (w > 65536 || h > 65536)
        Corrupt(path, "IHDR size " + std::to_string(w) + "x" + std::to_string(h) + " is too large");
    } else if (type == "tRNS" && !idat_seen) {
      return false;  // transparency: left to libpng, which turns it into an alpha channel
    } else if (type == "IDAT") {
      if (idat_closed) Corrupt(path, "IDAT chunks are not consecutive");
      if (!idat_seen) png->idat_begin = png->idat_end = pos + 8;
      // The destination is already-read header and CRC bytes.
      std::memmove(b + png->idat_end, data, len);
      png->idat_end += len;
      idat_seen = true;
    } else {
      if (idat_seen) idat_closed = true;
      iend = type == "IEND";
    }
    pos += 12 + static_cast<size_t>(len);
  }
  if (!idat_seen) Corrupt(path, "no IDAT chunk (no image data)");
  return true;
}

// Inflates the zlib stream into raw (raw_bytes: every row with its filter-type byte).
void Inflate(const uint8_t* zlib, size_t zlib_bytes, uint8_t* raw, size_t raw_bytes, const std::string& path) {
  libdeflate_decompressor* dec = libdeflate_alloc_decompressor();
  if (!dec) throw InputError(path, "out of memory decoding PNG");
  const libdeflate_result r = libdeflate_zlib_decompress(dec, zlib, zlib_bytes, raw, raw_bytes, nullptr);
  libdeflate_free_decompressor(dec);
  if (r == LIBDEFLATE_SHORT_OUTPUT) Corrupt(path, "IDAT holds fewer bytes than IHDR's size needs (truncated)");
  if (r == LIBDEFLATE_INSUFFICIENT_SPACE) Corrupt(path, "IDAT holds more bytes than IHDR's size");
  if (r != LIBDEFLATE_SUCCESS) Corrupt(path, "IDAT zlib stream is corrupt");
}

// Reverses each row's filter and stores the samples as uint16 (dst may overlap raw as DecodeGreyPng
// lays them out: row y's output starts y + 1 bytes before its input, which is copied out first).
void UnfilterRows(const uint8_t* raw, const PngLayout& png, uint16_t* dst, const std::string& path) {
  const int bpp = png.depth / 8;
  const size_t row_bytes = static_cast<size_t>(png.w) * bpp;
  std::vector<uint8_t> prev(row_bytes, 0), cur(row_bytes);
  for (uint32_t y = 0; y < png.h; ++y) {
    const uint8_t* src = raw + static_cast<size_t>(y) * (row_bytes + 1);
    std::memcpy(cur.data(), src + 1, row_bytes);
    if (!Unfilter(src[0], cur.data(), prev.data(), row_bytes, bpp)) {
      Corrupt(path, "row " + std::to_string(y) + " has unknown filter type " + std::to_string(src[0]));
    }
    uint16_t* row = dst + static_cast<size_t>(y) * png.w;
    if (png.depth == 16) {
      StoreBe16(cur.data(), row, png.w);
    } else {
      for (size_t x = 0; x < png.w; ++x) row[x] = cur[x];
    }
    prev.swap(cur);
  }
}

}  // namespace

bool DecodeGreyPng(std::vector<uint8_t>& bytes, const std::string& path, Frame* out) {
  static const uint8_t kSig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (bytes.size() < 8 || std::memcmp(bytes.data(), kSig, 8) != 0) return false;
  PngLayout png;
  if (!ReadChunks(bytes.data(), bytes.size(), path, &png)) return false;
  const uint32_t w = png.w, h = png.h;
  const size_t row_bytes = static_cast<size_t>(w) * (png.depth / 8);
  const size_t raw_bytes = (row_bytes + 1) * h;
  // Deflate expands at most ~1032:1: refuse before allocating what a short file cannot fill.
  if (raw_bytes / 1032 > png.idat_end - png.idat_begin + 64)
    Corrupt(path, "IDAT holds fewer bytes than IHDR's size needs (truncated)");
  Frame fr;
  fr.file = path;
  fr.bit_depth = png.depth;
  fr.saturation_adu = png.depth == 8 ? 255 : 65535;
  fr.image.width = static_cast<int>(w);
  fr.image.height = static_cast<int>(h);
  const size_t n_px = static_cast<size_t>(w) * h;
  // 16-bit: inflate straight into the frame's buffer, grown by h bytes for the filter-type bytes,
  // and unfilter row by row in place (row y's output starts y + 1 bytes before its input).
  // 8-bit: the output is twice the input, so inflate into a scratch buffer.
  std::unique_ptr<uint8_t[]> scratch;
  uint8_t* raw = nullptr;
  if (png.depth == 16) {
    fr.image.pixels.resize(n_px + (h + 1) / 2);
    raw = reinterpret_cast<uint8_t*>(fr.image.pixels.data());
  } else {
    fr.image.pixels.resize(n_px);
    scratch.reset(new uint8_t[raw_bytes]);
    raw = scratch.get();
  }
  Inflate(bytes.data() + png.idat_begin, png.idat_end - png.idat_begin, raw, raw_bytes, path);
  UnfilterRows(raw, png, fr.image.pixels.data(), path);
  fr.image.pixels.resize(n_px);
  *out = std::move(fr);
  return true;
}

}  // namespace ssiu
