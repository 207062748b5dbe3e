#include "flight/flight_config.h"

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <iomanip>
#include <sstream>

#include "core/astrometry.h"
#include "core/error.h"

namespace ssiu {
namespace {

// The text form's keys: each a name (head<k>. / gyro<k>. prefixed per head / gyro) and its numbers.
// kHotPixels: a head's list, its count n then n pairs x y (`p` is the head's ssiu_head_config).
enum class Kind { kInt, kDouble, kUint, kText, kHotPixels };
struct Field {
  std::string key;
  Kind kind;
  void* p;
  int count;
};

std::vector<Field> Fields(ssiu_flight_config* c) {
  std::vector<Field> f = {{"n_heads", Kind::kInt, &c->n_heads, 1},
                          {"n_gyros", Kind::kInt, &c->n_gyros, 1},
                          {"gyro_rate_hz", Kind::kDouble, &c->gyro_rate_hz, 1},
                          {"gyro_max_abs_dph", Kind::kDouble, &c->gyro_max_abs_dph, 1},
                          {"max_centroids", Kind::kInt, &c->max_centroids, 1},
                          {"max_stars_in_field", Kind::kInt, &c->max_stars_in_field, 1},
                          {"max_star_samples", Kind::kInt, &c->max_star_samples, 1},
                          {"max_bias_history", Kind::kInt, &c->max_bias_history, 1},
                          {"max_hypotheses", Kind::kInt, &c->max_hypotheses, 1},
                          {"max_patterns", Kind::kInt, &c->max_patterns, 1},
                          {"max_false_match_prob", Kind::kDouble, &c->max_false_match_prob, 1},
                          {"threshold_sigma", Kind::kDouble, &c->threshold_sigma, 1},
                          {"exposure_s", Kind::kDouble, &c->exposure_s, 1},
                          {"systematic_px", Kind::kDouble, &c->systematic_px, 1},
                          {"track_search_radius_px", Kind::kDouble, &c->track_search_radius_px, 1},
                          {"epoch_utc", Kind::kText, c->epoch_utc, 1},
                          {"velocity_kms", Kind::kDouble, c->velocity_kms, 3},
                          {"catalog_crc32", Kind::kUint, &c->catalog_crc32, 1},
                          {"calibrate_unit", Kind::kInt, &c->calibrate_unit, 1}};
  for (int h = 0; h < SSIU_FLIGHT_MAX_HEADS; ++h) {
    ssiu_head_config& x = c->heads[h];
    const std::string p = "head" + std::to_string(h + 1) + ".";
    f.push_back({p + "size_px", Kind::kInt, &x.width_px, 2});
    f.push_back({p + "focal_length_px", Kind::kDouble, &x.focal_length_px, 1});
    f.push_back({p + "focal_length_y_px", Kind::kDouble, &x.focal_length_y_px, 1});
    f.push_back({p + "principal_point_px", Kind::kDouble, &x.cx_px, 2});
    f.push_back({p + "distortion_k1_k2_k3_p1_p2", Kind::kDouble, &x.k1, 5});
    f.push_back({p + "gain_e_per_adu", Kind::kDouble, &x.gain_e_per_adu, 1});
    f.push_back({p + "q_body_sensor", Kind::kDouble, x.q_body_sensor, 4});
    f.push_back({p + "psf_sigma_px", Kind::kDouble, &x.psf_sigma_px, 1});
    f.push_back({p + "vignetting", Kind::kDouble, &x.vignetting, 1});
    f.push_back({p + "hot_pixels", Kind::kHotPixels, &x, 1});
  }
  for (int g = 0; g < SSIU_FLIGHT_MAX_GYROS; ++g) {
    ssiu_gyro_config& x = c->gyros[g];
    const std::string p = "gyro" + std::to_string(g + 1) + ".";
    f.push_back({p + "axis_body", Kind::kDouble, x.axis_body, 3});
    f.push_back({p + "arw_deg_per_sqrt_h", Kind::kDouble, &x.arw_deg_per_sqrt_h, 1});
    f.push_back({p + "bias_instability_dph", Kind::kDouble, &x.bias_instability_dph, 1});
    f.push_back({p + "rrw_dph_per_sqrt_h", Kind::kDouble, &x.rrw_dph_per_sqrt_h, 1});
  }
  return f;
}

// Whether a head<k>. / gyro<k>. key belongs to a head or gyro the config has.
bool InUse(const std::string& key, const ssiu_flight_config& c) {
  if (key.rfind("head", 0) == 0 && key.size() > 5 && key[5] == '.') return key[4] - '0' <= c.n_heads;
  if (key.rfind("gyro", 0) == 0 && key.size() > 5 && key[5] == '.') return key[4] - '0' <= c.n_gyros;
  return true;
}

// `key n x1 y1 ... xn yn`: whole numbers, n at most SSIU_FLIGHT_MAX_HOT_PIXELS, coordinates 0 to 65535
// (the image bounds are FlightSetupFrom's).
void ParseHotPixels(std::istringstream* ls, const std::string& where, const std::string& key, ssiu_head_config* x) {
  const auto next = [&](long lo, long hi, const char* what) {
    std::string word;
    if (!(*ls >> word)) throw InputError(where, "key '" + key + "' needs " + what);
    char* end = nullptr;
    errno = 0;
    const long v = std::strtol(word.c_str(), &end, 10);
    if (*end != '\0' || errno == ERANGE || v < lo || v > hi)
      throw InputError(where, "key '" + key + "': '" + word + "' is not a whole number from " + std::to_string(lo) +
                                  " to " + std::to_string(hi));
    return v;
  };
  x->n_hot_pixels = static_cast<int32_t>(next(0, SSIU_FLIGHT_MAX_HOT_PIXELS, "the count of hot pixels"));
  for (int k = 0; k < x->n_hot_pixels; ++k)
    for (int i = 0; i < 2; ++i)
      x->hot_pixels_xy[k][i] = static_cast<uint16_t>(next(0, UINT16_MAX, "x y per hot pixel"));
  std::string extra;
  if (*ls >> extra) throw InputError(where, "key '" + key + "' has more than its count of hot pixels");
}

}  // namespace

ssiu_flight_config FlightConfigFor(const std::vector<OpticalHead>& heads, const GyroUnit& unit,
                                   const UnitProcessorOptions& o, const std::string& epoch_utc,
                                   const Vec3& velocity_kms) {
  ssiu_flight_config c;
  std::memset(&c, 0, sizeof c);  // every field set below
  if (heads.empty() || heads.size() > SSIU_FLIGHT_MAX_HEADS)
    throw InputError("flight config", "1 to " + std::to_string(SSIU_FLIGHT_MAX_HEADS) + " heads");
  if (unit.size() < 3 || unit.size() > SSIU_FLIGHT_MAX_GYROS)
    throw InputError("flight config", "3 to " + std::to_string(SSIU_FLIGHT_MAX_GYROS) + " gyros");
  if (epoch_utc.size() >= sizeof c.epoch_utc) throw InputError("flight config", "epoch_utc too long");
  c.n_heads = static_cast<int32_t>(heads.size());
  for (size_t h = 0; h < heads.size(); ++h) {
    const Camera& cam = heads[h].camera;
    ssiu_head_config& x = c.heads[h];
    x.width_px = cam.width, x.height_px = cam.height;
    x.focal_length_px = cam.focal_length_px, x.focal_length_y_px = cam.focal_length_y_px;
    x.cx_px = cam.cx_px, x.cy_px = cam.cy_px;
    x.k1 = cam.distortion.k1, x.k2 = cam.distortion.k2, x.k3 = cam.distortion.k3;
    x.p1 = cam.distortion.p1, x.p2 = cam.distortion.p2;
    x.gain_e_per_adu = cam.gain_e_per_adu;
    const Quat q = heads[h].q_body_from_sensor.normalized();
    const double s = q.w() < 0 ? -1 : 1;
    x.q_body_sensor[0] = s * q.w(), x.q_body_sensor[1] = s * q.x();
    x.q_body_sensor[2] = s * q.y(), x.q_body_sensor[3] = s * q.z();
    const CameraExtras& e = heads[h].extras;
    x.psf_sigma_px = e.psf_sigma_px;
    x.vignetting = e.vignetting;
    if (e.hot_pixels.size() > SSIU_FLIGHT_MAX_HOT_PIXELS)
      throw InputError("flight config", "head" + std::to_string(h + 1) + ": more than " +
                                            std::to_string(SSIU_FLIGHT_MAX_HOT_PIXELS) + " hot pixels");
    x.n_hot_pixels = static_cast<int32_t>(e.hot_pixels.size());
    for (size_t k = 0; k < e.hot_pixels.size(); ++k) {
      for (int i = 0; i < 2; ++i) {
        const int v = e.hot_pixels[k][i];
        if (v < 0 || v > UINT16_MAX)
          throw InputError("flight config", "head" + std::to_string(h + 1) + ": hot pixel out of range");
        x.hot_pixels_xy[k][i] = static_cast<uint16_t>(v);
      }
    }
  }
  c.n_gyros = unit.size();
  for (int g = 0; g < unit.size(); ++g) {
    ssiu_gyro_config& x = c.gyros[g];
    for (int k = 0; k < 3; ++k) x.axis_body[k] = unit.axes_body[g][k];
    x.arw_deg_per_sqrt_h = unit.gyros[g].arw_deg_per_sqrt_h;
    x.bias_instability_dph = unit.gyros[g].bias_instability_dph;
    x.rrw_dph_per_sqrt_h = unit.gyros[g].rrw_dph_per_sqrt_h;
  }
  c.gyro_rate_hz = unit.rate_hz;
  c.gyro_max_abs_dph = o.fuse.policy.max_gyro_output_dph;
  c.max_centroids = o.solve.detect.max_stars;
  c.max_stars_in_field = o.max_stars_in_field;
  c.max_star_samples = o.fuse.policy.max_star_samples_kept;
  c.max_bias_history = o.fuse.policy.bias_history_max;
  c.max_hypotheses = o.solve.identify.max_hypotheses;
  c.max_patterns = o.solve.identify.max_patterns;
  c.max_false_match_prob = o.solve.identify.max_false_match_prob;
  c.threshold_sigma = o.solve.detect.threshold_sigma;
  c.exposure_s = o.solve.detect.smear.exposure_s;
  c.systematic_px = o.solve.identify.systematic_px;
  c.track_search_radius_px = o.solve.track_search_radius_px;
  c.calibrate_unit = o.fuse.calibrate_unit ? 1 : 0;
  std::memset(c.epoch_utc, 0, sizeof c.epoch_utc);
  std::memcpy(c.epoch_utc, epoch_utc.data(), epoch_utc.size());
  for (int k = 0; k < 3; ++k) c.velocity_kms[k] = velocity_kms[k];
  return c;
}

FlightSetup FlightSetupFrom(const ssiu_flight_config& c) {
  const std::string src = "flight config";
  if (c.n_heads < 1 || c.n_heads > SSIU_FLIGHT_MAX_HEADS) throw InputError(src, "n_heads must be 1 to 3");
  if (c.n_gyros < 3 || c.n_gyros > SSIU_FLIGHT_MAX_GYROS) throw InputError(src, "n_gyros must be 3 to 6");
  FlightSetup s;
  for (int h = 0; h < c.n_heads; ++h) {
    const ssiu_head_config& x = c.heads[h];
    OpticalHead head;
    Camera& cam = head.camera;
    cam.width = x.width_px, cam.height = x.height_px;
    cam.focal_length_px = x.focal_length_px, cam.focal_length_y_px = x.focal_length_y_px;
    cam.cx_px = x.cx_px, cam.cy_px = x.cy_px;
    cam.distortion = Distortion{x.k1, x.k2, x.k3, x.p1, x.p2};
    cam.gain_e_per_adu = x.gain_e_per_adu;
    const std::string where = "head" + std::to_string(h + 1);
    cam.Check(src + ": " + where);
    const Quat q(x.q_body_sensor[0], x.q_body_sensor[1], x.q_body_sensor[2], x.q_body_sensor[3]);
    if (!q.coeffs().allFinite() || std::abs(q.norm() - 1) > 1e-6)
      throw InputError(src, where + ".q_body_sensor must be a unit quaternion");
    head.q_body_from_sensor = q.normalized();
    if (!(x.vignetting >= 0 && x.vignetting < 1)) throw InputError(src, where + ".vignetting must be in [0, 1)");
    head.extras.vignetting = x.vignetting;
    if (!(x.psf_sigma_px >= 0 && x.psf_sigma_px < 50))
      throw InputError(src, where + ".psf_sigma_px must be in [0, 50)");
    head.extras.psf_sigma_px = x.psf_sigma_px;
    if (x.n_hot_pixels < 0 || x.n_hot_pixels > SSIU_FLIGHT_MAX_HOT_PIXELS)
      throw InputError(src, where + ".n_hot_pixels must be 0 to " + std::to_string(SSIU_FLIGHT_MAX_HOT_PIXELS));
    for (int k = 0; k < x.n_hot_pixels; ++k) {
      const int px = x.hot_pixels_xy[k][0], py = x.hot_pixels_xy[k][1];
      if (px >= cam.width || py >= cam.height)
        throw InputError(src, where + ".hot_pixels_xy[" + std::to_string(k) + "] lies outside the image");
      head.extras.hot_pixels.push_back({px, py});
    }
    s.heads.push_back(head);
  }
  for (int g = 0; g < c.n_gyros; ++g) {
    const ssiu_gyro_config& x = c.gyros[g];
    s.unit.axes_body.emplace_back(x.axis_body[0], x.axis_body[1], x.axis_body[2]);
    GyroErrorModel m;
    m.arw_deg_per_sqrt_h = x.arw_deg_per_sqrt_h;
    m.bias_instability_dph = x.bias_instability_dph;
    m.rrw_dph_per_sqrt_h = x.rrw_dph_per_sqrt_h;
    s.unit.gyros.push_back(m);
  }
  s.unit.rate_hz = c.gyro_rate_hz;
  s.unit.Check(src);
  if (!(c.gyro_max_abs_dph >= 0) || !std::isfinite(c.gyro_max_abs_dph))
    throw InputError(src, "gyro_max_abs_dph must be >= 0 (0 = no limit)");
  UnitProcessorOptions& o = s.options;
  o.diagnostics = false;  // no text or maps on the flight path
  if (c.gyro_max_abs_dph > 0) o.fuse.policy.max_gyro_output_dph = c.gyro_max_abs_dph;
  if (c.max_centroids < 4 || c.max_centroids > 100000) throw InputError(src, "max_centroids must be 4 to 100000");
  o.solve.detect.max_stars = c.max_centroids;
  if (c.max_stars_in_field < 1 || c.max_stars_in_field > 100000)
    throw InputError(src, "max_stars_in_field must be 1 to 100000");
  o.max_stars_in_field = c.max_stars_in_field;
  if (c.max_star_samples < 1 || c.max_star_samples > (1 << 20))
    throw InputError(src, "max_star_samples must be 1 to 1048576");
  if (c.max_bias_history < 1 || c.max_bias_history > (1 << 20))
    throw InputError(src, "max_bias_history must be 1 to 1048576");
  o.fuse.policy.max_star_samples_kept = c.max_star_samples;
  o.fuse.policy.bias_history_max = c.max_bias_history;
  o.solve.identify.max_hypotheses = c.max_hypotheses;
  o.solve.identify.max_patterns = c.max_patterns;
  o.solve.identify.max_false_match_prob = c.max_false_match_prob;
  o.solve.detect.threshold_sigma = c.threshold_sigma;
  o.solve.detect.smear.exposure_s = c.exposure_s;
  o.solve.identify.systematic_px = c.systematic_px;
  o.solve.track_search_radius_px = c.track_search_radius_px;
  if (c.calibrate_unit != 0 && c.calibrate_unit != 1) throw InputError(src, "calibrate_unit must be 0 or 1");
  if (c.calibrate_unit == 1 && c.n_gyros < 4) throw InputError(src, "calibrate_unit needs 4 or more gyros");
  o.fuse.calibrate_unit = c.calibrate_unit == 1;
  if (std::memchr(c.epoch_utc, 0, sizeof c.epoch_utc) == nullptr)
    throw InputError(src, "epoch_utc must be NUL-terminated");
  const std::string epoch(c.epoch_utc);
  const Vec3 v_kms(c.velocity_kms[0], c.velocity_kms[1], c.velocity_kms[2]);
  if (!v_kms.allFinite() || v_kms.norm() > 100) throw InputError(src, "velocity_kms must be at most 100 km/s");
  if (!epoch.empty()) {
    o.solve.sky.time = ParseUtcIso8601(epoch, src + ": epoch_utc");
    o.solve.sky.have_velocity = v_kms.norm() > 0;
    o.solve.sky.velocity_m_s = v_kms * 1000.0;
  } else if (v_kms.norm() > 0) {
    throw InputError(src, "velocity_kms needs epoch_utc (aberration is computed at a date)");
  }
  o.Check();
  return s;
}

std::string FlightConfigText(const ssiu_flight_config& config) {
  ssiu_flight_config c = config;
  std::ostringstream out;
  out << "# ssiu flight configuration (ssiu_flight.h; docs/flight.md)\n" << std::setprecision(17);
  for (const Field& f : Fields(&c)) {
    if (!InUse(f.key, c)) continue;
    out << f.key;
    for (int i = 0; i < f.count; ++i) {
      switch (f.kind) {
        case Kind::kInt:
          out << ' ' << static_cast<const int32_t*>(f.p)[i];
          break;
        case Kind::kDouble:
          out << ' ' << static_cast<const double*>(f.p)[i];
          break;
        case Kind::kUint:
          out << ' ' << static_cast<const uint32_t*>(f.p)[i];
          break;
        case Kind::kText:
          out << ' ' << (c.epoch_utc[0] ? c.epoch_utc : "-");
          break;
        case Kind::kHotPixels: {
          const ssiu_head_config& x = *static_cast<const ssiu_head_config*>(f.p);
          const int n = std::clamp(x.n_hot_pixels, 0, SSIU_FLIGHT_MAX_HOT_PIXELS);
          out << ' ' << n;
          for (int k = 0; k < n; ++k) out << ' ' << x.hot_pixels_xy[k][0] << ' ' << x.hot_pixels_xy[k][1];
          break;
        }
      }
    }
    out << '\n';
  }
  return out.str();
}

ssiu_flight_config ParseFlightConfigText(const std::string& text, const std::string& source) {
  ssiu_flight_config c;
  ssiu_flight_default_config(&c);
  const std::vector<Field> fields = Fields(&c);
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream ls(line);
    std::string key;
    if (!(ls >> key)) continue;
    const std::string where = source + ":" + std::to_string(line_no);
    const Field* f = nullptr;
    for (const Field& x : fields)
      if (x.key == key) f = &x;
    if (!f) throw InputError(where, "unknown key '" + key + "'");
    if (f->kind == Kind::kHotPixels) {
      ParseHotPixels(&ls, where, key, static_cast<ssiu_head_config*>(f->p));
      continue;
    }
    for (int i = 0; i < f->count; ++i) {
      std::string word;
      if (!(ls >> word)) throw InputError(where, "key '" + key + "' needs " + std::to_string(f->count) + " values");
      char* end = nullptr;
      errno = 0;
      switch (f->kind) {
        case Kind::kInt: {
          const long v = std::strtol(word.c_str(), &end, 10);
          if (v < INT32_MIN || v > INT32_MAX) end = nullptr;
          static_cast<int32_t*>(f->p)[i] = static_cast<int32_t>(v);
          break;
        }
        case Kind::kUint: {
          const unsigned long v = std::strtoul(word.c_str(), &end, 10);
          if (v > UINT32_MAX || word[0] == '-') end = nullptr;
          static_cast<uint32_t*>(f->p)[i] = static_cast<uint32_t>(v);
          break;
        }
        case Kind::kDouble: {
          const double v = std::strtod(word.c_str(), &end);
          if (!std::isfinite(v)) end = nullptr;
          static_cast<double*>(f->p)[i] = v;
          break;
        }
        case Kind::kText:
          if (word.size() >= sizeof c.epoch_utc) throw InputError(where, "key '" + key + "': value too long");
          std::memset(c.epoch_utc, 0, sizeof c.epoch_utc);
          if (word != "-") std::memcpy(c.epoch_utc, word.data(), word.size());
          end = &word[word.size()];
          break;
        case Kind::kHotPixels:  // read whole above
          break;
      }
      if (end == nullptr || *end != '\0' || errno == ERANGE)
        throw InputError(where, "key '" + key + "': '" + word + "' is not a valid number");
    }
    std::string extra;
    if (ls >> extra) throw InputError(where, "key '" + key + "' has more than " + std::to_string(f->count) + " values");
  }
  return c;
}

}  // namespace ssiu
