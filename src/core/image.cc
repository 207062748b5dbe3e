#include "core/image.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/fits_lazy.h"
#include "core/output.h"
#include "core/png_decode.h"
#include "core/raster_codec.h"

namespace ssiu {
namespace {

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

bool IsFitsName(const std::string& path) {
  const std::string ext = Lower(std::filesystem::path(path).extension().string());
  return ext == ".fits" || ext == ".fit" || ext == ".fts";
}

bool HasFitsMagic(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char buf[9] = {0};
  in.read(buf, 9);
  return in.gcount() == 9 && std::string(buf, 9) == "SIMPLE  =";
}

Frame ReadFits(const std::string& path) {
  fitsfile* f = nullptr;
  int status = 0;
  auto fail = [&](const std::string& what) -> InputError {
    int s2 = 0;
    if (f) Cfitsio().close_file(f, &s2);
    return InputError(path, what);
  };
  if (Cfitsio().open_diskfile(&f, path.c_str(), READONLY, &status)) {
    f = nullptr;
    throw fail("not a readable FITS file (corrupt or truncated)");
  }
  std::string date_obs;
  {
    char value[FLEN_VALUE] = "";
    int key_status = 0;  // a missing key is not an error
    if (Cfitsio().read_key(f, TSTRING, "DATE-OBS", value, nullptr, &key_status) == 0) date_obs = value;
  }
  int bitpix = 0, naxis = 0;
  long naxes[3] = {0, 0, 0};
  if (Cfitsio().get_img_param(f, 3, &bitpix, &naxis, naxes, &status)) throw fail("cannot read the FITS image header");
  if (naxis < 2 || (naxis == 3 && naxes[2] != 1) || naxis > 3) {
    throw fail("FITS primary HDU must hold a 2-D image (NAXIS=" + std::to_string(naxis) + ")");
  }
  if (bitpix != 8 && bitpix != 16 && bitpix != 32 && bitpix != -32 && bitpix != -64) {
    throw fail("unsupported FITS BITPIX " + std::to_string(bitpix));
  }
  const long w = naxes[0], h = naxes[1];
  if (w <= 0 || h <= 0) throw fail("FITS image has zero size");
  if (w > 65536 || h > 65536) throw fail("FITS image is too large");
  {
    // A header that declares more pixels than the file holds would allocate gigabytes before the
    // read fails: compare with the data the file actually has after its header.
    LONGLONG header_start = 0, data_start = 0, data_end = 0;
    std::error_code ec;
    const auto file_bytes = std::filesystem::file_size(path, ec);
    if (!Cfitsio().get_hduaddrll(f, &header_start, &data_start, &data_end, &status) && !ec &&
        static_cast<LONGLONG>(file_bytes) < data_start + static_cast<LONGLONG>(w) * h * (std::abs(bitpix) / 8)) {
      throw fail("FITS data is shorter than its header's NAXIS1 x NAXIS2 x BITPIX (truncated)");
    }
  }
  long first[3] = {1, 1, 1};
  int anynul = 0;
  int equivtype = 0;
  if (Cfitsio().get_img_equivtype(f, &equivtype, &status)) throw fail("cannot read the FITS image header");
  if (equivtype == BYTE_IMG || equivtype == USHORT_IMG) {
    // Integers that fit uint16 exactly (8-bit, or 16-bit with BZERO 32768): read straight into the
    // frame; the double round trip below costs several ms per megapixel.
    Frame fr;
    fr.file = path;
    fr.image = Image16(static_cast<int>(w), static_cast<int>(h));
    if (Cfitsio().read_pix(f, TUSHORT, first, static_cast<LONGLONG>(fr.image.pixels.size()), nullptr,
                           fr.image.pixels.data(), &anynul, &status)) {
      throw fail("cannot read FITS pixel data (truncated?)");
    }
    Cfitsio().close_file(f, &status);
    fr.bit_depth = equivtype == BYTE_IMG ? 8 : 16;
    fr.saturation_adu = equivtype == BYTE_IMG ? 255 : 65535;
    fr.date_obs = date_obs;
    return fr;
  }
  std::vector<double> buf(static_cast<size_t>(w) * static_cast<size_t>(h));
  double nulval = std::nan("");
  if (Cfitsio().read_pix(f, TDOUBLE, first, static_cast<LONGLONG>(buf.size()), &nulval, buf.data(), &anynul, &status)) {
    throw fail("cannot read FITS pixel data (truncated?)");
  }
  Cfitsio().close_file(f, &status);
  double lo = INFINITY, hi = -INFINITY;
  for (double v : buf) {
    if (!std::isfinite(v)) throw InputError(path, "FITS pixel data contains NaN or infinite values");
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  Frame fr;
  fr.file = path;
  fr.date_obs = date_obs;
  fr.image = Image16(static_cast<int>(w), static_cast<int>(h));
  const bool integral = bitpix > 0 && lo >= 0 && hi <= 65535;
  if (integral) {
    for (size_t i = 0; i < buf.size(); ++i) fr.image.pixels[i] = static_cast<uint16_t>(std::lround(buf[i]));
    fr.bit_depth = bitpix == 8 ? 8 : 16;
    fr.saturation_adu = bitpix == 8 ? 255 : 65535;
  } else {
    // Map the data range linearly onto 0..65535; results are scaled back to the file's units.
    const double span = hi > lo ? hi - lo : 1.0;
    fr.value_scale = span / 65535.0;
    fr.value_offset = lo;
    for (size_t i = 0; i < buf.size(); ++i) {
      fr.image.pixels[i] = static_cast<uint16_t>(std::lround((buf[i] - lo) / fr.value_scale));
    }
    fr.saturation_adu = 65535;
  }
  return fr;
}

// Decoded samples -> a grey frame: colour reduced to the mean of R, G, B (alpha ignored; rounded to
// nearest, as OpenCV's convertTo did), grey+alpha to its grey (conventions.md).
Frame FrameFromSamples(const RasterSamples& r, const std::string& path) {
  Frame fr;
  fr.file = path;
  fr.bit_depth = r.depth;
  fr.saturation_adu = r.depth == 8 ? 255 : 65535;
  fr.image = Image16(r.width, r.height);
  const size_t n = fr.image.pixels.size(), ch = static_cast<size_t>(r.channels);
  const uint16_t* s = r.samples.data();
  uint16_t* d = fr.image.pixels.data();
  if (ch == 1) {
    std::copy(s, s + n, d);
  } else if (ch == 2) {
    for (size_t i = 0; i < n; ++i) d[i] = s[2 * i];
    fr.grey_conversion = "first_of_grey_alpha";
  } else {
    // Mean of the three colour channels: keeps each channel's signal with equal weight (the
    // openstartracker frames have unequal channels). (a + b + c + 1) / 3 is the nearest integer.
    for (size_t i = 0; i < n; ++i) {
      const uint32_t sum = uint32_t{s[ch * i]} + s[ch * i + 1] + s[ch * i + 2];
      d[i] = static_cast<uint16_t>((sum + 1) / 3);
    }
    fr.grey_conversion = "mean_rgb";
  }
  return fr;
}

// PNG (the fast grey decoder, else libpng), TIFF (libtiff), JPEG or BMP (libturbojpeg); anything else is
// refused.
Frame ReadRaster(const std::string& path, int64_t max_side_px) {
  std::vector<uint8_t> bytes;
  {
    std::ifstream in(path, std::ios::binary);
    in.seekg(0, std::ios::end);
    const std::streamoff n = in.tellg();
    if (!in || n <= 0) throw InputError(path, "cannot read file");
    // The head says the format: TIFF and BMP are read by their libraries from the file (BMP's header,
    // 26 bytes, checked here first), PNG and JPEG from the bytes read once here.
    bytes.resize(static_cast<size_t>(std::min<std::streamoff>(n, 26)));
    in.seekg(0);
    in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    if (IsTiff(bytes)) return FrameFromSamples(DecodeTiff(path, max_side_px), path);
    if (IsBmp(bytes)) return FrameFromSamples(DecodeBmp(bytes, path, max_side_px), path);
    static const uint8_t kSig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    const bool png = bytes.size() >= 8 && std::equal(kSig, kSig + 8, bytes.begin());
    if (!png && !IsJpeg(bytes)) {
      throw InputError(path, "cannot decode image (corrupt, truncated or not PNG/TIFF/FITS/JPEG/BMP)");
    }
    bytes.resize(static_cast<size_t>(n));
    in.seekg(0);
    in.read(reinterpret_cast<char*>(bytes.data()), n);
    if (!in) throw InputError(path, "read failed");
    if (!png) return FrameFromSamples(DecodeJpeg(bytes, path, max_side_px), path);
  }
  // The common case, non-interlaced 8/16-bit grey PNG, has its own fast decoder (png_decode.h). It
  // packs the IDAT chunks in place, but declines (returns false) only before the first IDAT, so libpng
  // gets the file as read (no copy of it: ~0.5 ms of a 1 Mpx frame's start, issue 17).
  Frame fast;
  if (DecodeGreyPng(bytes, path, &fast)) return fast;
  return FrameFromSamples(DecodePngLibpng(bytes, path, max_side_px), path);
}

}  // namespace

void CheckFrameContent(const Frame& fr) {
  const auto& px = fr.image.pixels;
  if (px.empty()) throw InputError(fr.file, "image has zero size");
  // One pass with plain min/max/count accumulators (vectorises; minmax_element and count do not).
  const uint16_t sat = static_cast<uint16_t>(fr.saturation_adu);
  const uint16_t* p = px.data();
  const size_t n = px.size();
  uint16_t lo = 65535, hi = 0;
  size_t n_sat = 0;
  for (size_t i = 0; i < n; ++i) {
    lo = p[i] < lo ? p[i] : lo;
    hi = p[i] > hi ? p[i] : hi;
    n_sat += p[i] == sat;
  }
  if (lo == hi) {
    throw InputError(fr.file, "image is constant (every pixel = " + std::to_string(hi) + "): no signal");
  }
  if (n_sat * 2 > px.size()) {
    throw InputError(fr.file,
                     "image is saturated (" + std::to_string(100 * n_sat / px.size()) + "% of pixels at full scale)");
  }
}

ImageLimits ImageLimits::FromEnvironment() {
  ImageLimits l;
  auto env = [](const char* name, int64_t lo, int64_t hi, int64_t* out, int64_t unit) {
    const char* v = std::getenv(name);
    if (!v || !*v) return;
    char* end = nullptr;
    const double d = std::strtod(v, &end);
    if (*end != '\0' || !(d >= static_cast<double>(lo) && d <= static_cast<double>(hi))) {
      throw InputError(name, std::string("must be a number in [") + std::to_string(lo) + ", " + std::to_string(hi) +
                                 "], not '" + v + "'");
    }
    *out = static_cast<int64_t>(d) * unit;
  };
  env("SSIU_MAX_IMAGE_SIDE_PX", 16, 65536, &l.max_side_px, 1);
  env("SSIU_MAX_INPUT_MB", 1, 1 << 20, &l.max_file_bytes, int64_t{1} << 20);
  return l;
}

bool DeclaredImageSize(const std::string& path, int64_t* width, int64_t* height) {
  std::ifstream in(path, std::ios::binary);
  unsigned char b[32] = {0};
  in.read(reinterpret_cast<char*>(b), sizeof b);
  const std::streamsize n = in.gcount();
  auto be32 = [&](int i) {
    return (uint32_t(b[i]) << 24) | (uint32_t(b[i + 1]) << 16) | (uint32_t(b[i + 2]) << 8) | b[i + 3];
  };
  if (n >= 24 && b[0] == 0x89 && b[1] == 'P' && b[2] == 'N' && b[3] == 'G' && std::string(b + 12, b + 16) == "IHDR") {
    *width = be32(16), *height = be32(20);  // PNG 11.2.2: IHDR is the first chunk
    return true;
  }
  if (n >= 8 && ((b[0] == 'I' && b[1] == 'I' && b[2] == 42 && b[3] == 0) ||
                 (b[0] == 'M' && b[1] == 'M' && b[2] == 0 && b[3] == 42))) {
    // TIFF 6.0 section 2: the first IFD's ImageWidth (256) and ImageLength (257), SHORT or LONG.
    const bool le = b[0] == 'I';
    auto u = [&](const unsigned char* p, int bytes) {
      uint32_t v = 0;
      for (int i = 0; i < bytes; ++i) v |= uint32_t(p[le ? i : bytes - 1 - i]) << (8 * i);
      return v;
    };
    const uint32_t ifd = u(b + 4, 4);
    in.clear();
    in.seekg(ifd);
    unsigned char cnt[2];
    if (!in.read(reinterpret_cast<char*>(cnt), 2)) return false;
    const uint32_t entries = u(cnt, 2);
    int64_t w = -1, h = -1;
    for (uint32_t k = 0; k < entries && k < 4096; ++k) {
      unsigned char e[12];
      if (!in.read(reinterpret_cast<char*>(e), 12)) return false;
      const uint32_t tag = u(e, 2), type = u(e + 2, 2);
      const uint32_t value = type == 3 ? u(e + 8, 2) : u(e + 8, 4);
      if (tag == 256) w = value;
      if (tag == 257) h = value;
    }
    if (w < 0 || h < 0) return false;
    *width = w, *height = h;
    return true;
  }
  if (n >= 9 && std::string(b, b + 9) == "SIMPLE  =") {
    fitsfile* f = nullptr;
    int status = 0, naxis = 0;
    long naxes[2] = {0, 0};
    if (Cfitsio().open_diskfile(&f, path.c_str(), READONLY, &status)) return false;
    Cfitsio().get_img_dim(f, &naxis, &status);
    if (!status && naxis >= 2) Cfitsio().get_img_size(f, 2, naxes, &status);
    int s2 = 0;
    Cfitsio().close_file(f, &s2);
    if (status || naxis < 2) return false;
    *width = naxes[0], *height = naxes[1];
    return true;
  }
  return false;
}

Frame ReadFrame(const std::string& path) { return ReadFrame(path, ImageLimits::FromEnvironment()); }

Frame ReadFrame(const std::string& path, const ImageLimits& limits) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(path, "no such file");
  if (std::filesystem::is_directory(path, ec)) throw InputError(path, "is a directory, not an image");
  const auto bytes = std::filesystem::file_size(path, ec);
  if (!ec && bytes == 0) throw InputError(path, "file is empty");
  if (!ec && static_cast<int64_t>(bytes) > limits.max_file_bytes) {
    throw InputError(path, std::to_string(bytes) + " bytes, more than the input limit of " +
                               std::to_string(limits.max_file_bytes) + " (SSIU_MAX_INPUT_MB)");
  }
  int64_t w = 0, h = 0;
  if (DeclaredImageSize(path, &w, &h) && (w > limits.max_side_px || h > limits.max_side_px)) {
    throw InputError(path, "declares " + std::to_string(w) + " x " + std::to_string(h) +
                               " pixels, more than the limit of " + std::to_string(limits.max_side_px) +
                               " per side (SSIU_MAX_IMAGE_SIDE_PX)");
  }
  Frame fr = (IsFitsName(path) || HasFitsMagic(path)) ? ReadFits(path) : ReadRaster(path, limits.max_side_px);
  if (fr.image.width > limits.max_side_px || fr.image.height > limits.max_side_px) {
    throw InputError(path, "image is larger than the limit of " + std::to_string(limits.max_side_px) + " px per side");
  }
  CheckFrameContent(fr);
  return fr;
}

Frame SubtractDark(const Frame& frame, const Frame& dark, double pedestal_adu) {
  if (dark.image.width != frame.image.width || dark.image.height != frame.image.height) {
    throw InputError(dark.file, "dark frame is " + std::to_string(dark.image.width) + "x" +
                                    std::to_string(dark.image.height) + ", image is " +
                                    std::to_string(frame.image.width) + "x" + std::to_string(frame.image.height));
  }
  Frame out = frame;
  const uint16_t sat = static_cast<uint16_t>(frame.saturation_adu);
  for (size_t i = 0; i < out.image.pixels.size(); ++i) {
    const uint16_t v = frame.image.pixels[i];
    const double d = v - double(dark.image.pixels[i]) * dark.value_scale / frame.value_scale + pedestal_adu;
    out.image.pixels[i] = v >= sat ? 65535 : static_cast<uint16_t>(std::clamp(std::round(d), 0.0, 65534.0));
  }
  out.saturation_adu = 65535;
  out.value_offset = frame.value_offset - pedestal_adu * frame.value_scale;
  return out;
}

void CheckPngOutputName(const std::string& path) {
  const std::string ext = Lower(std::filesystem::path(path).extension().string());
  if (!ext.empty() && ext != ".png") {
    throw InputError(path, "unsupported extension '" + ext + "': this output is a PNG (give FILE.png)");
  }
}

std::string PngBytes(const void* pixels, int width, int height, int channels, int depth, size_t stride_bytes,
                     int level) {
  if ((depth != 8 && depth != 16) || channels < 1 || channels > 4 || width < 1 || height < 1 ||
      stride_bytes < static_cast<size_t>(width) * channels * (depth / 8)) {
    throw std::invalid_argument("PngBytes: only 8/16-bit images of 1-4 channels");
  }
  // Rows packed, and OpenCV's colour order BGR(A) turned into PNG's RGB(A).
  const size_t row = static_cast<size_t>(width) * channels;
  std::vector<uint16_t> wide;
  std::vector<uint8_t> narrow;
  (depth == 8 ? narrow.resize(row * height) : wide.resize(row * height));
  for (int y = 0; y < height; ++y) {
    const char* line = static_cast<const char*>(pixels) + y * stride_bytes;
    for (size_t i = 0; i < row; ++i) {
      const size_t c = i % channels, src = channels >= 3 && c < 3 ? i - c + (2 - c) : i;  // B <-> R
      if (depth == 8) {
        narrow[y * row + i] = reinterpret_cast<const uint8_t*>(line)[src];
      } else {
        uint16_t v;
        std::memcpy(&v, line + 2 * src, 2);
        wide[y * row + i] = v;
      }
    }
  }
  return EncodePng(depth == 8 ? static_cast<const void*>(narrow.data()) : wide.data(), width, height, channels, depth,
                   level);
}

void WritePng(const std::string& path, const void* pixels, int width, int height, int channels, int depth,
              size_t stride_bytes) {
  // The format is PNG whatever the name says: a name with another extension is a usage error (once an
  // OpenCV exception, exit 2), a name without one (or a device such as /dev/stdout) is fine.
  CheckPngOutputName(path);
  std::string png;
  try {
    png = PngBytes(pixels, width, height, channels, depth, stride_bytes);
  } catch (const std::invalid_argument&) {
    throw InputError(path, "cannot encode PNG");
  }
  WriteFileAtomic(path, png);
}

void WritePng16(const std::string& path, const Image16& image) {
  WritePng(path, image.pixels.data(), image.width, image.height, 1, 16, static_cast<size_t>(image.width) * 2);
}

void WritePgm16(const std::string& path, const Image16& image) {
  std::string bytes = "P5\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n65535\n";
  const size_t header = bytes.size();
  bytes.resize(header + 2 * image.pixels.size());
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    bytes[header + 2 * i] = static_cast<char>(image.pixels[i] >> 8);
    bytes[header + 2 * i + 1] = static_cast<char>(image.pixels[i] & 0xff);
  }
  WriteFileAtomic(path, bytes);
}

void WritePng8(const std::string& path, int width, int height, const std::vector<uint8_t>& pixels) {
  WritePng(path, pixels.data(), width, height, 1, 8, static_cast<size_t>(width));
}

void WriteFits16(const std::string& path, const Image16& image) {
  WriteFileViaTemp(path, [&](const std::string& temp) {
    fitsfile* f = nullptr;
    int status = 0;
    long naxes[2] = {image.width, image.height};
    if (Cfitsio().create_file(&f, temp.c_str(), &status)) throw InputError(path, "cannot create FITS file");
    Cfitsio().create_img(f, USHORT_IMG, 2, naxes, &status);
    long first[2] = {1, 1};
    Cfitsio().write_pix(f, TUSHORT, first, static_cast<LONGLONG>(image.pixels.size()),
                        const_cast<uint16_t*>(image.pixels.data()), &status);
    Cfitsio().close_file(f, &status);
    if (status) throw InputError(path, "cannot write FITS file");
  });
}

}  // namespace ssiu
