#include "groundtest/mask.h"

#include <apriltag/apriltag.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "core/attitude.h"
#include "core/error.h"
#include "core/image.h"
#include "core/output.h"
#include "groundtest/apriltag_family.h"

namespace ssiu {

void MaskOptions::Check() const {
  auto bad = [](const std::string& f, const std::string& w) { throw InputError("mask options", f + " " + w); };
  if (!(collimator_focal_mm > 0) || !std::isfinite(collimator_focal_mm)) bad("collimator_focal_mm", "must be > 0");
  if (!(mag_max >= 0) || !std::isfinite(mag_max)) bad("mag_max", "must be >= 0");
  if (!(margin_deg >= 0 && margin_deg < 20)) bad("margin_deg", "must be in [0, 20)");
  if (!(hole_min_diameter_mm >= 0) || !(hole_max_diameter_mm >= 0)) bad("hole diameters", "must be >= 0");
  if (hole_min_diameter_mm > 0 && hole_max_diameter_mm > 0 && hole_max_diameter_mm < hole_min_diameter_mm)
    bad("hole_max_diameter_mm", "must be >= hole_min_diameter_mm");
  if (!(tag_size_mm >= 0)) bad("tag_size_mm", "must be >= 0");
  if (first_tag_id < 0 || first_tag_id + 8 > 587) bad("first_tag_id", "must leave 8 tag36h11 codes (0..579)");
}

std::array<Vec2, 4> MaskTag::Corners() const {
  const double h = size_mm / 2;
  return {Vec2(x_mm - h, y_mm + h), Vec2(x_mm + h, y_mm + h), Vec2(x_mm + h, y_mm - h), Vec2(x_mm - h, y_mm - h)};
}

Vec3 Mask::DirectionOf(double x_mm, double y_mm) const { return Vec3(x_mm, y_mm, collimator_focal_mm).normalized(); }

Mask DesignMask(const Camera& camera, StarSpan stars, const Quat& q_design,
                const MaskOptions& o) {
  o.Check();
  camera.Check();
  Mask m;
  m.camera = camera;
  m.collimator_focal_mm = o.collimator_focal_mm;
  m.q_design = q_design.normalized();
  m.distortion_compensated = o.compensate_distortion;
  const RaDecRoll a = RaDecRollFromQuat(m.q_design);
  m.ra_deg = a.ra_rad * kRadToDeg, m.dec_deg = a.dec_rad * kRadToDeg, m.roll_deg = a.roll_rad * kRadToDeg;
  const double F = o.collimator_focal_mm;
  const double margin = o.margin_deg * kDegToRad;
  // The field covers the tracker's pixels (corners unprojected, so distortion widens it correctly).
  double tx = 0, ty = 0;
  for (double px : {-0.5, camera.width - 0.5})
    for (double py : {-0.5, camera.height - 0.5}) {
      const Vec3 d = camera.Unproject(Vec2(px, py));
      tx = std::max(tx, std::abs(d.x() / d.z()));
      ty = std::max(ty, std::abs(d.y() / d.z()));
    }
  m.field_half_x_mm = F * std::tan(std::atan(tx) + margin);
  m.field_half_y_mm = F * std::tan(std::atan(ty) + margin);
  const double pixel_mm = F / camera.FocalMinPx();  // the larger pixel side
  m.hole_min_diameter_mm = o.hole_min_diameter_mm > 0 ? o.hole_min_diameter_mm : 0.2 * pixel_mm;
  m.hole_max_diameter_mm = o.hole_max_diameter_mm > 0 ? o.hole_max_diameter_mm : 2.0 * pixel_mm;
  m.hole_max_diameter_mm = std::max(m.hole_max_diameter_mm, m.hole_min_diameter_mm);
  double faint = -99;
  for (const auto& s : stars)
    if (o.mag_max == 0 || s.mag <= o.mag_max) faint = std::max(faint, s.mag);
  m.mag_faint = o.mag_max > 0 ? o.mag_max : faint;
  const Quat q_m_from_i = m.q_design.conjugate();
  for (const auto& s : stars) {
    if (o.mag_max > 0 && s.mag > o.mag_max) continue;
    Vec3 d = q_m_from_i * s.unit;
    if (d.z() <= 0) continue;
    if (o.compensate_distortion) {
      // The direction whose distorted image is the star's pinhole image.
      const Vec2 pin(camera.cx_px + camera.focal_length_px * d.x() / d.z(),
                     camera.cy_px + camera.FocalYPx() * d.y() / d.z());
      d = camera.Unproject(pin);
      // Far outside the image the lens model has no inverse: leave out what it cannot show.
      const auto back = camera.Project(d);
      if (!back || (*back - pin).norm() > 1e-3) continue;
    }
    const double x = F * d.x() / d.z(), y = F * d.y() / d.z();
    if (std::abs(x) > m.field_half_x_mm || std::abs(y) > m.field_half_y_mm) continue;
    MaskHole h;
    h.star_id = s.id, h.mag = s.mag, h.x_mm = x, h.y_mm = y;
    // Flux ~ area ~ d^2: d = d_min * 10^(0.2 (m_faint - m)).
    h.diameter_mm = m.hole_min_diameter_mm * std::pow(10.0, 0.2 * (m.mag_faint - s.mag));
    if (h.diameter_mm > m.hole_max_diameter_mm) {
      h.diameter_mm = m.hole_max_diameter_mm;
      ++m.clamped_holes;
    }
    h.mag_effective = m.mag_faint - 5.0 * std::log10(h.diameter_mm / m.hole_min_diameter_mm);
    m.holes.push_back(h);
  }
  std::stable_sort(m.holes.begin(), m.holes.end(), [](const MaskHole& p, const MaskHole& q) { return p.mag < q.mag; });
  // Eight fiducials just outside the star field: corners and edge midpoints.
  const double size = o.tag_size_mm > 0 ? o.tag_size_mm : 0.12 * 2 * std::max(m.field_half_x_mm, m.field_half_y_mm);
  const double outer = size * 10.0 / 8.0;  // with tag36h11's white ring (10 of 8 cells)
  const double gx = m.field_half_x_mm + 0.5 * size + outer / 2, gy = m.field_half_y_mm + 0.5 * size + outer / 2;
  const double pos[8][2] = {{-1, -1}, {0, -1}, {1, -1}, {1, 0}, {1, 1}, {0, 1}, {-1, 1}, {-1, 0}};
  for (int i = 0; i < 8; ++i) {
    MaskTag t;
    t.id = o.first_tag_id + i;
    t.x_mm = pos[i][0] * gx, t.y_mm = pos[i][1] * gy;
    t.size_mm = size;
    m.tags.push_back(t);
  }
  m.plate_half_mm = std::max(gx, gy) + outer / 2 + 0.25 * size;
  return m;
}

Json MaskToJson(const Mask& m) {
  Json j;
  j["format"] = "ssiu_mask_v1";
  j["camera"] = CameraToJson(m.camera);
  j["collimator_focal_mm"] = m.collimator_focal_mm;
  const auto q = ToWxyz(m.q_design);
  j["design"] = {
      {"q", {q[0], q[1], q[2], q[3]}}, {"ra_deg", m.ra_deg}, {"dec_deg", m.dec_deg}, {"roll_deg", m.roll_deg}};
  j["frame"] = "plate mm: x right, y down as seen from the collimator lens; hole (x,y) -> direction (x,y,F)/|.|";
  j["field_half_x_mm"] = m.field_half_x_mm, j["field_half_y_mm"] = m.field_half_y_mm;
  j["plate_side_mm"] = 2 * m.plate_half_mm;
  j["hole_grading"] = {{"law", "d = d_min * 10^(0.2 (mag_faint - mag)), capped at d_max"},
                       {"mag_faint", m.mag_faint},
                       {"d_min_mm", m.hole_min_diameter_mm},
                       {"d_max_mm", m.hole_max_diameter_mm},
                       {"clamped_holes", m.clamped_holes}};
  Json holes = Json::array();
  for (const auto& h : m.holes)
    holes.push_back({{"star_id", h.star_id},
                     {"mag", h.mag},
                     {"mag_effective", h.mag_effective},
                     {"x_mm", h.x_mm},
                     {"y_mm", h.y_mm},
                     {"diameter_mm", h.diameter_mm}});
  j["holes"] = holes;
  j["tag_family"] = m.tag_family;
  j["distortion_compensated"] = m.distortion_compensated;
  Json tags = Json::array();
  for (const auto& t : m.tags) {
    Json c = Json::array();
    for (const auto& p : t.Corners()) c.push_back({p.x(), p.y()});
    tags.push_back({{"id", t.id}, {"x_mm", t.x_mm}, {"y_mm", t.y_mm}, {"size_mm", t.size_mm}, {"corners_mm", c}});
  }
  j["tags"] = tags;
  return j;
}

Mask MaskFromJson(const Json& j, const std::string& src) {
  if (!j.is_object()) throw InputError(src, "not a mask (JSON object expected)");
  if (!j.contains("format") || j["format"] != "ssiu_mask_v1") throw InputError(src, "format: not ssiu_mask_v1");
  CheckKeys(
      j,
      {"format", "camera", "collimator_focal_mm", "design", "frame", "field_half_x_mm", "field_half_y_mm",
       "plate_side_mm", "hole_grading", "holes", "tag_family", "distortion_compensated", "tags", "png_dpi", "comment"},
      src);
  Mask m;
  if (!j.contains("camera")) throw InputError(src, "camera: missing");
  m.camera = CameraFromJson(j["camera"], src + ": camera");
  m.collimator_focal_mm = JsonNumber(j, "collimator_focal_mm", src);
  if (!(m.collimator_focal_mm > 0)) throw InputError(src, "collimator_focal_mm: must be > 0");
  if (!j.contains("design") || !j["design"].contains("q") || !j["design"]["q"].is_array() ||
      j["design"]["q"].size() != 4)
    throw InputError(src, "design.q: missing or not [w,x,y,z]");
  CheckKeys(j["design"], {"q", "ra_deg", "dec_deg", "roll_deg"}, src + ": design");
  const auto& q = j["design"]["q"];
  for (const auto& v : q)
    if (!v.is_number()) throw InputError(src, "design.q: must hold numbers");
  m.q_design = FromWxyz(q[0], q[1], q[2], q[3], "design.q");
  m.ra_deg = JsonNumberOr(j["design"], "ra_deg", 0, src);
  m.dec_deg = JsonNumberOr(j["design"], "dec_deg", 0, src);
  m.roll_deg = JsonNumberOr(j["design"], "roll_deg", 0, src);
  m.field_half_x_mm = JsonNumber(j, "field_half_x_mm", src);
  m.field_half_y_mm = JsonNumber(j, "field_half_y_mm", src);
  m.plate_half_mm = JsonNumber(j, "plate_side_mm", src) / 2;
  if (j.contains("hole_grading")) {
    CheckKeys(j["hole_grading"], {"law", "mag_faint", "d_min_mm", "d_max_mm", "clamped_holes"}, src + ": hole_grading");
    m.mag_faint = JsonNumberOr(j["hole_grading"], "mag_faint", 0, src);
    m.hole_min_diameter_mm = JsonNumberOr(j["hole_grading"], "d_min_mm", 0, src);
    m.hole_max_diameter_mm = JsonNumberOr(j["hole_grading"], "d_max_mm", 0, src);
  }
  if (!j.contains("holes") || !j["holes"].is_array()) throw InputError(src, "holes: missing");
  for (size_t i = 0; i < j["holes"].size(); ++i) {
    const Json& h = j["holes"][i];
    const std::string w = src + ": holes[" + std::to_string(i) + "]";
    MaskHole mh;
    CheckKeys(h, {"star_id", "mag", "mag_effective", "x_mm", "y_mm", "diameter_mm"}, w);
    mh.star_id = static_cast<StarId>(JsonInt(h, "star_id", -1, 2000000000, w));
    mh.mag = JsonNumber(h, "mag", w);
    mh.mag_effective = JsonNumberOr(h, "mag_effective", mh.mag, w);
    mh.x_mm = JsonNumber(h, "x_mm", w), mh.y_mm = JsonNumber(h, "y_mm", w);
    mh.diameter_mm = JsonNumber(h, "diameter_mm", w);
    if (!(mh.diameter_mm > 0)) throw InputError(w, "diameter_mm: must be > 0");
    m.holes.push_back(mh);
  }
  m.tag_family = JsonStringOr(j, "tag_family", "tag36h11", src);
  m.distortion_compensated = JsonBoolOr(j, "distortion_compensated", m.distortion_compensated, src);
  if (!groundtest_internal::CreateFamily(m.tag_family))
    throw InputError(src, "tag_family: unknown '" + m.tag_family + "'");
  if (!j.contains("tags") || !j["tags"].is_array()) throw InputError(src, "tags: missing");
  for (size_t i = 0; i < j["tags"].size(); ++i) {
    const Json& t = j["tags"][i];
    const std::string w = src + ": tags[" + std::to_string(i) + "]";
    MaskTag mt;
    CheckKeys(t, {"id", "x_mm", "y_mm", "size_mm", "corners_mm"}, w);
    mt.id = static_cast<int>(JsonInt(t, "id", 0, 1000000, w));
    mt.x_mm = JsonNumber(t, "x_mm", w), mt.y_mm = JsonNumber(t, "y_mm", w);
    mt.size_mm = JsonNumber(t, "size_mm", w);
    if (!(mt.size_mm > 0)) throw InputError(w, "size_mm: must be > 0");
    m.tags.push_back(mt);
  }
  return m;
}

Mask LoadMask(const std::string& path) { return MaskFromJson(ReadJsonFile(path), path); }
void SaveMask(const Mask& m, const std::string& path) { WriteJsonFile(path, MaskToJson(m)); }

void CheckMaskCamera(const Mask& m, const Camera& c, const std::string& mask_file) {
  const Camera& d = m.camera;
  if (d.width != c.width || d.height != c.height ||
      std::abs(d.focal_length_px - c.focal_length_px) > 1e-3 * d.focal_length_px ||
      std::abs(d.FocalYPx() - c.FocalYPx()) > 1e-3 * d.FocalYPx() || std::abs(d.cx_px - c.cx_px) > 0.5 ||
      std::abs(d.cy_px - c.cy_px) > 0.5) {
    char buf[256];
    std::snprintf(buf, sizeof buf, "designed for another camera (%dx%d, f %.1f px), not this one (%dx%d, f %.1f px)",
                  d.width, d.height, d.focal_length_px, c.width, c.height, c.focal_length_px);
    throw InputError(mask_file, buf);
  }
}

std::vector<uint8_t> TagPattern(const std::string& family, int id, int* total_width_cells) {
  auto fam = groundtest_internal::CreateFamily(family);
  if (!fam) throw InputError("tag family", "unknown '" + family + "'");
  if (id < 0 || static_cast<uint32_t>(id) >= fam->ncodes)
    throw InputError("tag id",
                     std::to_string(id) + " outside " + family + " (0.." + std::to_string(fam->ncodes - 1) + ")");
  // Drawn from the family's tables the way libapriltag's apriltag_to_image does (that function's
  // image type is not exported by the Debian library): a one-cell white ring (unless the family has
  // a reversed border), black elsewhere, and the code's 1-bits white at (bit_x, bit_y) from the
  // black border's corner, most significant bit first.
  const int n = fam->total_width;
  std::vector<uint8_t> out(static_cast<size_t>(n) * n, 0);
  const int ring = fam->width_at_border + (fam->reversed_border ? 0 : 2);
  const int r0 = (n - ring) / 2, r1 = r0 + ring - 1;
  for (int i = r0; i <= r1; ++i) {
    out[static_cast<size_t>(r0) * n + i] = out[static_cast<size_t>(r1) * n + i] = 255;
    out[static_cast<size_t>(i) * n + r0] = out[static_cast<size_t>(i) * n + r1] = 255;
  }
  const int b0 = (n - fam->width_at_border) / 2;
  const uint64_t code = fam->codes[id];
  for (uint32_t i = 0; i < fam->nbits; ++i)
    if (code & (uint64_t{1} << (fam->nbits - i - 1)))
      out[static_cast<size_t>(fam->bit_y[i] + b0) * n + fam->bit_x[i] + b0] = 255;
  *total_width_cells = n;
  return out;
}

namespace {

// Cell size (mm) of a tag: its black square spans width_at_border cells.
double TagCellMm(const std::string& family, const MaskTag& t) {
  auto fam = groundtest_internal::CreateFamily(family);
  return t.size_mm / fam->width_at_border;
}

}  // namespace

void WriteMaskSvg(const Mask& m, const std::string& path) {
  WriteFileAtomic(path, [&](std::ostream& f) {
    const double s = 2 * m.plate_half_mm;
    f << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << s << "mm\" height=\"" << s << "mm\" viewBox=\""
      << -m.plate_half_mm << ' ' << -m.plate_half_mm << ' ' << s << ' ' << s << "\">\n";
    f << "<!-- ssiu star mask: plate mm, x right, y down as seen from the collimator lens; F = "
      << m.collimator_focal_mm << " mm; design ra " << m.ra_deg << " dec " << m.dec_deg << " roll " << m.roll_deg
      << " deg -->\n";
    f << "<rect x=\"" << -m.plate_half_mm << "\" y=\"" << -m.plate_half_mm << "\" width=\"" << s << "\" height=\"" << s
      << "\" fill=\"black\"/>\n";
    f.precision(10);
    for (const auto& h : m.holes)
      f << "<circle cx=\"" << h.x_mm << "\" cy=\"" << h.y_mm << "\" r=\"" << h.diameter_mm / 2
        << "\" fill=\"white\"><title>HR " << h.star_id << " V " << h.mag << "</title></circle>\n";
    for (const auto& t : m.tags) {
      int n = 0;
      const std::vector<uint8_t> p = TagPattern(m.tag_family, t.id, &n);
      const double c = TagCellMm(m.tag_family, t);
      const double x0 = t.x_mm - n * c / 2, y0 = t.y_mm - n * c / 2;
      f << "<g><title>" << m.tag_family << " id " << t.id << "</title>\n";
      f << "<rect x=\"" << x0 << "\" y=\"" << y0 << "\" width=\"" << n * c << "\" height=\"" << n * c
        << "\" fill=\"white\"/>\n";
      for (int r = 0; r < n; ++r)
        for (int k = 0; k < n; ++k)
          if (p[static_cast<size_t>(r) * n + k] < 128)
            f << "<rect x=\"" << x0 + k * c << "\" y=\"" << y0 + r * c << "\" width=\"" << c << "\" height=\"" << c
              << "\" fill=\"black\"/>\n";
      f << "</g>\n";
    }
    f << "</svg>\n";
  });
}

}  // namespace ssiu
