#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/error.h"
#include "core/image.h"
#include "detect/background.h"
#include "detect/detect.h"

namespace ssiu {

void DefectMapOptions::Check() const {
  if (!std::isfinite(sigma) || sigma < 3) throw InputError("DefectMapOptions: sigma must be >= 3");
  if (tile_px < 8) throw InputError("DefectMapOptions: tile_px must be >= 8");
}

DefectMap BuildDefectMap(const std::vector<ImageView>& frames, const DefectMapOptions& o) {
  o.Check();
  if (frames.empty()) throw InputError("BuildDefectMap: no frames");
  const int w = frames[0].width, h = frames[0].height;
  for (const auto& f : frames) {
    if (f.width != w || f.height != h) throw InputError("BuildDefectMap: frames differ in size");
  }
  // Votes per pixel: a defect stands out from the local background in most frames (a star or a
  // cosmic ray does so in one frame only; with a single median frame, one vote decides).
  std::vector<uint16_t> hot(static_cast<size_t>(w) * h, 0), dead(hot.size(), 0);
  ScratchVec<float> hi(w), lo(w);
  for (const auto& f : frames) {
    const BackgroundGrid bg = EstimateBackground(f, o.tile_px);
    for (int y = 0; y < h; ++y) {
      bg.RowLevels(y, &hi, o.sigma, 1.0);
      bg.RowLevels(y, &lo, -o.sigma, 1.0);
      const uint16_t* r = f.row(y);
      for (int x = 0; x < w; ++x) {
        const size_t i = static_cast<size_t>(y) * w + x;
        if (r[x] > hi[x]) {
          // Sharper than any optical image: the pixel stands above its 4 neighbours' mean by most of
          // its own excess (a star's peak pixel does not).
          const double nb = 0.25 * (f.at(std::max(x - 1, 0), y) + f.at(std::min(x + 1, w - 1), y) +
                                    f.at(x, std::max(y - 1, 0)) + f.at(x, std::min(y + 1, h - 1)));
          const double lvl = bg.LevelAt(x, y);
          if (nb - lvl < 0.5 * (r[x] - lvl)) ++hot[i];
        }
        if (r[x] < lo[x]) ++dead[i];
      }
    }
  }
  DefectMap m;
  m.width = w;
  m.height = h;
  m.mask.assign(hot.size(), 0);
  const size_t need = frames.size() / 2 + 1;
  for (size_t i = 0; i < hot.size(); ++i) {
    if (hot[i] >= need)
      m.mask[i] = 1;
    else if (dead[i] >= need)
      m.mask[i] = 2;
  }
  return m;
}

void MarkHotPixel(int x, int y, int width, int height, DefectMap* map, const std::string& where) {
  if (x < 0 || x >= width || y < 0 || y >= height || (!map->empty() && (map->width != width || map->height != height)))
    throw InputError(where, "hot pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") lies outside the " +
                                std::to_string(width) + "x" + std::to_string(height) + " image or its defect map");
  if (map->empty()) {
    map->width = width, map->height = height;
    map->mask.assign(static_cast<size_t>(width) * height, 0);
  }
  map->mask[static_cast<size_t>(y) * map->width + x] = 1;
}

void MarkHotPixels(const std::vector<std::array<int, 2>>& pixels, int width, int height, DefectMap* map,
                   const std::string& where) {
  for (const auto& p : pixels) MarkHotPixel(p[0], p[1], width, height, map, where);
}

DefectMap LoadDefectMap(const std::string& path) {
  const Frame f = [&] {
    try {
      return ReadFrame(path);
    } catch (const InputError& e) {
      // A map with no defects is a constant image: that is fine here.
      if (std::string(e.what()).find("constant") == std::string::npos) throw;
      Frame blank;
      return blank;
    }
  }();
  DefectMap m;
  if (f.image.pixels.empty()) return m;  // all-good map
  m.width = f.image.width;
  m.height = f.image.height;
  m.mask.resize(f.image.pixels.size());
  // A map holds only the levels SaveDefectMap writes (8-bit 0, 64, 128, 255; the same levels scaled
  // to 16 bits): anything else, such as a star frame given by mistake, is refused at its first pixel.
  const int scale = f.bit_depth == 8 ? 1 : 257;
  for (size_t i = 0; i < m.mask.size(); ++i) {
    const int v = f.image.pixels[i];
    if (v == 0)
      m.mask[i] = 0;
    else if (v == 255 * scale)
      m.mask[i] = 1;
    else if (v == 128 * scale)
      m.mask[i] = 2;
    else if (v == 64 * scale)
      m.mask[i] = 3;
    else {
      throw InputError(path, "not a defect map: pixel (" + std::to_string(i % m.width) + ", " +
                                 std::to_string(i / m.width) + ") is " + std::to_string(v) +
                                 "; a map holds only 0 (good), 255 (hot), 128 (dead) and 64 (other)" +
                                 (scale > 1 ? " times 257" : ""));
    }
  }
  return m;
}

void SaveDefectMap(const std::string& path, const DefectMap& m) {
  std::vector<uint8_t> px(m.mask.size());
  for (size_t i = 0; i < px.size(); ++i) px[i] = m.mask[i] == 1 ? 255 : (m.mask[i] == 2 ? 128 : (m.mask[i] ? 64 : 0));
  WritePng8(path, m.width, m.height, px);
}

}  // namespace ssiu
