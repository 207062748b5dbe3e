#include "sim/frame_sim.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>

#include "core/attitude.h"
#include "core/error.h"
#include "core/rng.h"
#include "detect/smear.h"

namespace ssiu {
namespace {

// One table of the options' JSON names, so that the JSON config, its writer and the CLI flags
// (src/cli/simulate_frame.cc) cannot drift apart.
struct DoubleField {
  const char* name;
  double FrameSimOptions::*ptr;
};
struct IntField {
  const char* name;
  int FrameSimOptions::*ptr;
};
const DoubleField kDoubleFields[] = {
    {"psf_sigma_px", &FrameSimOptions::psf_sigma_px},
    {"defocus_radius_px", &FrameSimOptions::defocus_radius_px},
    {"psf_ellipticity", &FrameSimOptions::psf_ellipticity},
    {"psf_angle_deg", &FrameSimOptions::psf_angle_deg},
    {"psf_sigma_corner_px", &FrameSimOptions::psf_sigma_corner_px},
    {"exposure_s", &FrameSimOptions::exposure_s},
    {"rate_x_dps", &FrameSimOptions::rate_x_dps},
    {"rate_y_dps", &FrameSimOptions::rate_y_dps},
    {"rate_z_dps", &FrameSimOptions::rate_z_dps},
    {"velocity_x_kms", &FrameSimOptions::velocity_x_kms},
    {"velocity_y_kms", &FrameSimOptions::velocity_y_kms},
    {"velocity_z_kms", &FrameSimOptions::velocity_z_kms},
    {"mag0_flux_e_per_s", &FrameSimOptions::mag0_flux_e_per_s},
    {"mag_max", &FrameSimOptions::mag_max},
    {"vignetting", &FrameSimOptions::vignetting},
    {"background_e_per_s", &FrameSimOptions::background_e_per_s},
    {"background_gradient_e_per_s", &FrameSimOptions::background_gradient_e_per_s},
    {"background_gradient_angle_deg", &FrameSimOptions::background_gradient_angle_deg},
    {"dark_current_e_per_s", &FrameSimOptions::dark_current_e_per_s},
    {"read_noise_e", &FrameSimOptions::read_noise_e},
    {"gain_e_per_adu", &FrameSimOptions::gain_e_per_adu},
    {"bias_adu", &FrameSimOptions::bias_adu},
    {"full_well_e", &FrameSimOptions::full_well_e},
    {"hot_pixel_min_e_per_s", &FrameSimOptions::hot_pixel_min_e_per_s},
    {"hot_pixel_max_e_per_s", &FrameSimOptions::hot_pixel_max_e_per_s},
    {"cosmic_ray_e_per_px", &FrameSimOptions::cosmic_ray_e_per_px},
    {"cosmic_ray_max_length_px", &FrameSimOptions::cosmic_ray_max_length_px},
    {"streak_flux_e_per_px", &FrameSimOptions::streak_flux_e_per_px},
};
const IntField kIntFields[] = {
    {"bit_depth", &FrameSimOptions::bit_depth},     {"defect_seed", &FrameSimOptions::defect_seed},
    {"hot_pixels", &FrameSimOptions::hot_pixels},   {"dead_pixels", &FrameSimOptions::dead_pixels},
    {"cosmic_rays", &FrameSimOptions::cosmic_rays}, {"streaks", &FrameSimOptions::streaks},
    {"false_stars", &FrameSimOptions::false_stars},
};

// Integral of a unit 1-D Gaussian (centre c, sigma s) over the pixel [i - 0.5, i + 0.5].
inline double PixelFraction(int i, double c, double s) {
  const double k = 1.0 / (std::sqrt(2.0) * s);
  return 0.5 * (std::erf((i + 0.5 - c) * k) - std::erf((i - 0.5 - c) * k));
}

// Adds `flux` electrons of a pixel-integrated Gaussian at (x, y) to the signal image.
void AddGaussian(std::vector<double>& img, int w, int h, double x, double y, double sigma, double flux) {
  const int r = static_cast<int>(std::ceil(5 * sigma)) + 1;
  const int x0 = std::max(0, static_cast<int>(std::floor(x)) - r),
            x1 = std::min(w - 1, static_cast<int>(std::ceil(x)) + r);
  const int y0 = std::max(0, static_cast<int>(std::floor(y)) - r),
            y1 = std::min(h - 1, static_cast<int>(std::ceil(y)) + r);
  if (x0 > x1 || y0 > y1) return;
  std::vector<double> fx(x1 - x0 + 1), fy(y1 - y0 + 1);
  for (int i = x0; i <= x1; ++i) fx[i - x0] = PixelFraction(i, x, sigma);
  for (int j = y0; j <= y1; ++j) fy[j - y0] = PixelFraction(j, y, sigma);
  for (int j = y0; j <= y1; ++j) {
    double* row = &img[static_cast<size_t>(j) * w];
    const double a = flux * fy[j - y0];
    for (int i = x0; i <= x1; ++i) row[i] += a * fx[i - x0];
  }
}

// The local PSF: Gaussian core sigma (mean, sqrt of (a^2 + b^2) / 2), its ellipticity as
// e = (a^2 - b^2) / (a^2 + b^2) (FitSpot's |e1 + i e2|), and the major axis' direction.
struct PsfShape {
  double sigma = 1, e = 0, cos_th = 1, sin_th = 0;
};

// Adds a pixel-integrated elliptical Gaussian: the round Gaussian of the minor sigma b (exact erf
// integrals) convolved with a 1-D Gaussian of sigma s = sqrt(a^2 - b^2) along the major axis, the
// latter by the trapezoid rule at steps of half min(s, b) over +-5 s (for a Gaussian integrand the
// rule's error falls as exp(-2 pi^2 (width / step)^2): negligible at width / step = 2).
void AddEllipticalGaussian(std::vector<double>& img, int w, int h, double x, double y, const PsfShape& p, double flux) {
  if (p.e <= 0) {
    AddGaussian(img, w, h, x, y, p.sigma, flux);
    return;
  }
  const double b = p.sigma * std::sqrt(1 - p.e), s = p.sigma * std::sqrt(2 * p.e);
  const double step = 0.5 * std::min(s, b);
  const int k = static_cast<int>(std::ceil(5 * s / step));
  std::vector<double> wt(2 * k + 1);
  double sum = 0;
  for (int j = -k; j <= k; ++j) sum += wt[j + k] = std::exp(-0.5 * std::pow(j * step / s, 2));
  for (int j = -k; j <= k; ++j) {
    const double t = j * step;
    AddGaussian(img, w, h, x + t * p.cos_th, y + t * p.sin_th, b, flux * wt[j + k] / sum);
  }
}

// A star image: Gaussian, or for a defocused system a uniform disk (sampled on a sunflower
// pattern of sub-sources) blurred by the Gaussian.
void AddPsf(std::vector<double>& img, int w, int h, double x, double y, const FrameSimOptions& o, const PsfShape& p,
            double flux) {
  if (o.defocus_radius_px <= 0) {
    AddEllipticalGaussian(img, w, h, x, y, p, flux);
    return;
  }
  const int n = std::max(16, static_cast<int>(8 * o.defocus_radius_px * o.defocus_radius_px));
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int k = 0; k < n; ++k) {
    const double r = o.defocus_radius_px * std::sqrt((k + 0.5) / n), th = k * golden;
    AddEllipticalGaussian(img, w, h, x + r * std::cos(th), y + r * std::sin(th), p, flux / n);
  }
}

// A straight track of `e_per_px` electrons per pixel of length, sampled every 0.1 px, with
// blur sigma `sigma` (0 = deposited directly into the pixel, as a cosmic ray's charge is).
void AddTrack(std::vector<double>& img, int w, int h, double x0, double y0, double x1, double y1, double e_per_px,
              double sigma) {
  const double len = std::hypot(x1 - x0, y1 - y0);
  const int n = std::max(1, static_cast<int>(std::ceil(len / 0.1)));
  const double q = e_per_px * std::max(len, 1.0) / n;
  for (int k = 0; k < n; ++k) {
    const double t = (k + 0.5) / n, x = x0 + t * (x1 - x0), y = y0 + t * (y1 - y0);
    if (sigma > 0) {
      AddGaussian(img, w, h, x, y, sigma, q);
    } else {
      const int i = static_cast<int>(std::lround(x)), j = static_cast<int>(std::lround(y));
      if (i >= 0 && j >= 0 && i < w && j < h) img[static_cast<size_t>(j) * w + i] += q;
    }
  }
}

}  // namespace

void FrameSimOptions::Check() const {
  auto need = [](bool ok, const char* field, const char* what) {
    if (!ok) throw InputError("frame simulator options", std::string("field '") + field + "' " + what);
  };
  for (const auto& f : kDoubleFields) need(std::isfinite(this->*f.ptr), f.name, "must be finite");
  need(psf_sigma_px > 0.1 && psf_sigma_px < 50, "psf_sigma_px", "must be in (0.1, 50)");
  need(defocus_radius_px >= 0 && defocus_radius_px < 100, "defocus_radius_px", "must be in [0, 100)");
  // 0.95 (axis ratio 1:20) already costs ~200 Gaussians per star.
  need(psf_ellipticity >= 0 && psf_ellipticity <= 0.95, "psf_ellipticity", "must be in [0, 0.95]");
  need(std::abs(psf_angle_deg) <= 360, "psf_angle_deg", "must be in [-360, 360]");
  need(psf_sigma_corner_px == 0 || (psf_sigma_corner_px > 0.1 && psf_sigma_corner_px < 50), "psf_sigma_corner_px",
       "must be 0 (= psf_sigma_px) or in (0.1, 50)");
  need(background_gradient_e_per_s >= 0 && background_gradient_e_per_s <= 1e9, "background_gradient_e_per_s",
       "must be in [0, 1e9]");
  need(std::abs(background_gradient_angle_deg) <= 360, "background_gradient_angle_deg", "must be in [-360, 360]");
  need(exposure_s > 0, "exposure_s", "must be > 0");
  need(std::abs(rate_x_dps) <= 90, "rate_x_dps", "must be in [-90, 90]");
  need(std::abs(rate_y_dps) <= 90, "rate_y_dps", "must be in [-90, 90]");
  need(std::abs(rate_z_dps) <= 90, "rate_z_dps", "must be in [-90, 90]");
  need(Vec3(velocity_x_kms, velocity_y_kms, velocity_z_kms).norm() <= 100, "velocity_x_kms",
       "(with velocity_y_kms, velocity_z_kms) must be at most 100 km/s");
  need(!time_utc.empty() || Vec3(velocity_x_kms, velocity_y_kms, velocity_z_kms).norm() == 0, "velocity_x_kms",
       "(and y, z) needs time_utc (the annual aberration is the larger part)");
  if (!time_utc.empty()) ParseUtcIso8601(time_utc, "frame simulator options: field 'time_utc'");
  need(mag0_flux_e_per_s >= 0, "mag0_flux_e_per_s", "must be >= 0");
  need(vignetting >= 0 && vignetting <= 1, "vignetting", "must be in [0, 1]");
  need(background_e_per_s >= 0, "background_e_per_s", "must be >= 0");
  need(dark_current_e_per_s >= 0, "dark_current_e_per_s", "must be >= 0");
  need(read_noise_e >= 0, "read_noise_e", "must be >= 0");
  need(gain_e_per_adu > 0, "gain_e_per_adu", "must be > 0");
  need(bias_adu >= 0, "bias_adu", "must be >= 0");
  need(full_well_e > 0, "full_well_e", "must be > 0");
  need(bit_depth == 8 || bit_depth == 16, "bit_depth", "must be 8 or 16");
  need(hot_pixels >= 0 && dead_pixels >= 0 && cosmic_rays >= 0 && streaks >= 0 && false_stars >= 0, "hot_pixels",
       "(and other counts) must be >= 0");
  // 1e8 of any of them ran for hours (2e9 hot pixels ran out of memory).
  need(hot_pixels <= 1000000 && dead_pixels <= 1000000, "hot_pixels", "(and dead_pixels) must be at most 1e6");
  need(cosmic_rays <= 100000 && streaks <= 10000 && false_stars <= 100000, "cosmic_rays",
       "must be at most 1e5 (streaks 1e4, false_stars 1e5)");
  need(hot_pixel_min_e_per_s > 0 && hot_pixel_max_e_per_s >= hot_pixel_min_e_per_s, "hot_pixel_min_e_per_s",
       "must be > 0 and <= hot_pixel_max_e_per_s");
  need(cosmic_ray_e_per_px >= 0 && cosmic_ray_max_length_px >= 0, "cosmic_ray_e_per_px", "must be >= 0");
  need(streak_flux_e_per_px >= 0, "streak_flux_e_per_px", "must be >= 0");
}

FrameSimOptions FrameSimOptionsFromJson(const Json& j, const std::string& source) {
  if (!j.is_object()) throw InputError(source, "simulator config must be a JSON object");
  std::vector<std::string> names = FrameSimOptionNames();
  for (const char* n : {"shot_noise", "proper_motion", "aberration", "time_utc"}) names.push_back(n);
  CheckKeys(j, names, source);
  FrameSimOptions o;
  for (const auto& f : kDoubleFields) o.*f.ptr = JsonNumberOr(j, f.name, o.*f.ptr, source);
  // Range checked before the conversion: 4294967299 must not wrap into another field's complaint.
  for (const auto& f : kIntFields) {
    o.*f.ptr = static_cast<int>(
        JsonIntOr(j, f.name, o.*f.ptr, std::numeric_limits<int>::min(), std::numeric_limits<int>::max(), source));
  }
  o.shot_noise = JsonBoolOr(j, "shot_noise", o.shot_noise, source);
  o.proper_motion = JsonBoolOr(j, "proper_motion", o.proper_motion, source);
  o.aberration = JsonBoolOr(j, "aberration", o.aberration, source);
  o.time_utc = JsonStringOr(j, "time_utc", o.time_utc, source);
  try {
    o.Check();
  } catch (const InputError& e) {
    throw InputError(source, e.what());
  }
  return o;
}

Json FrameSimOptionsToJson(const FrameSimOptions& o) {
  Json j;
  for (const auto& f : kDoubleFields) j[f.name] = o.*f.ptr;
  for (const auto& f : kIntFields) j[f.name] = o.*f.ptr;
  j["shot_noise"] = o.shot_noise;
  j["time_utc"] = o.time_utc;
  j["proper_motion"] = o.proper_motion;
  j["aberration"] = o.aberration;
  return j;
}

std::vector<std::string> FrameSimOptionNames() {
  std::vector<std::string> names;
  for (const auto& f : kDoubleFields) names.push_back(f.name);
  for (const auto& f : kIntFields) names.push_back(f.name);
  return names;
}

void SetFrameSimOption(FrameSimOptions* o, const std::string& name, double value) {
  *o = FrameSimOptionsFromJson(
      [&] {
        Json j = FrameSimOptionsToJson(*o);
        if (!j.contains(name) || !j[name].is_number())
          throw InputError("frame simulator options", "unknown option '" + name + "'");
        j[name] = value;
        return j;
      }(),
      "frame simulator options");
}

SkyCorrections SkyForSimulation(const FrameSimOptions& o) {
  SkyCorrections s;
  if (o.time_utc.empty()) return s;
  s.time = ParseUtcIso8601(o.time_utc, "frame simulator options: field 'time_utc'");
  s.proper_motion = o.proper_motion;
  s.annual_aberration = o.aberration;
  s.velocity_m_s = Vec3(o.velocity_x_kms, o.velocity_y_kms, o.velocity_z_kms) * 1000.0;
  s.have_velocity = o.aberration && s.velocity_m_s.norm() > 0;
  return s;
}

Quat RandomAttitude(uint64_t seed) {
  Rng rng(seed ^ 0x9E3779B97F4A7C15ULL);
  const double u1 = rng.Uniform(), u2 = rng.Uniform(), u3 = rng.Uniform();
  return QuatFromUniform(u1, u2, u3);
}

namespace {

// A track artefact (streak or cosmic ray) from (x0, y0), `len` px long at angle `th`, clipped to the frame.
SimArtefact Track(const char* type, double x0, double y0, double len, double th, int w, int h) {
  SimArtefact a;
  a.type = type;
  a.x0_px = x0;
  a.y0_px = y0;
  a.x1_px = std::clamp(a.x0_px + len * std::cos(th), 0.0, w - 1.0);
  a.y1_px = std::clamp(a.y0_px + len * std::sin(th), 0.0, h - 1.0);
  a.x_px = 0.5 * (a.x0_px + a.x1_px);
  a.y_px = 0.5 * (a.y0_px + a.y1_px);
  return a;
}

// The frame SimulateFrame draws: the signal image (electrons) and the optics, motion and noise model its
// steps share. Each step draws from the generator it is given, so the frame's draw sequence is the
// order of the calls in SimulateFrame.
class FrameRenderer {
 public:
  FrameRenderer(const Camera& cam, const FrameSimOptions& o, SimulatedFrame* out);

  void AddCatalogStars(const StarCatalog& catalog);
  void AddFalseStars(Rng& rng);
  void AddStreaks(Rng& rng);
  void AddCosmicRays(Rng& rng);
  std::vector<uint8_t> AddSensorDefects();
  void ReadOut(const std::vector<uint8_t>& dead, Rng& rng);

 private:
  double Vignette(double x, double y) const;
  PsfShape ShapeAt(double x, double y) const;
  std::optional<Vec2> PathAt(const Vec3& v_mid, double t) const;
  std::vector<Vec2> SmearPath(const Vec2& p, const Vec3& v_mid, double* smear_px) const;
  void AddStar(StarId id, double mag, const Vec2& p, const Vec3& v_mid);

  // Sub-step of the integration along a moving star's path.
  static constexpr double kSmearStepPx = 0.1;

  const Camera& cam_;
  const FrameSimOptions& o_;
  SimulatedFrame& out_;
  const int w_, h_;
  std::vector<double> signal_;  // electrons
  double bg_e_ = 0;             // background + dark charge per pixel
  double var_bg_e2_ = 0;        // its noise per pixel (electrons^2), for the SNR truth
  PsfShape shape0_;             // the PSF at the centre
  bool varying_sigma_ = false;
  double area_factor_ = 1;   // an elliptical Gaussian's area / a round one's of the mean sigma
  double sigma_max_px_ = 0;  // the widest PSF anywhere (major-axis sigma)
  Vec3 rate_rad_s_ = Vec3::Zero();
  bool moving_ = false;
  double smear_margin_px_ = 0;
};

FrameRenderer::FrameRenderer(const Camera& cam, const FrameSimOptions& o, SimulatedFrame* out)
    : cam_(cam), o_(o), out_(*out), w_(cam.width), h_(cam.height), signal_(static_cast<size_t>(w_) * h_, 0.0) {
  bg_e_ = (o.background_e_per_s + o.dark_current_e_per_s) * o.exposure_s;
  var_bg_e2_ =
      (o.shot_noise ? bg_e_ : 0.0) + o.read_noise_e * o.read_noise_e + o.gain_e_per_adu * o.gain_e_per_adu / 12.0;
  // The PSF at an image position: sigma(r) and the fixed ellipse (axes in pixel coordinates).
  const double axis_ratio2 = (1 - o.psf_ellipticity) * (1 - o.psf_ellipticity);
  shape0_.sigma = o.psf_sigma_px;
  shape0_.e = (1 - axis_ratio2) / (1 + axis_ratio2);
  shape0_.cos_th = std::cos(o.psf_angle_deg * kDegToRad), shape0_.sin_th = std::sin(o.psf_angle_deg * kDegToRad);
  varying_sigma_ = o.psf_sigma_corner_px > 0 && o.psf_sigma_corner_px != o.psf_sigma_px;
  // An elliptical Gaussian's area scales with a b = sigma^2 sqrt(1 - e^2).
  area_factor_ = std::sqrt(1 - shape0_.e * shape0_.e);
  // The widest PSF anywhere (major-axis sigma) for the margin of stars drawn outside the frame.
  sigma_max_px_ = std::max(o.psf_sigma_px, o.psf_sigma_corner_px) * std::sqrt(1 + shape0_.e);
  // Motion during the exposure (detect/smear.h for the kinematics).
  rate_rad_s_ = Vec3(o.rate_x_dps, o.rate_y_dps, o.rate_z_dps) * kDegToRad;
  moving_ = rate_rad_s_.squaredNorm() > 0;
  // Stars up to half a smear outside the frame at mid-exposure run into it (half a smear is at most
  // |w| T / 2 times the focal length plus the half diagonal, pinhole; 1.5x for distortion).
  smear_margin_px_ = 1.5 * 0.5 * rate_rad_s_.norm() * o.exposure_s *
                     (std::max(cam.focal_length_px, cam.FocalYPx()) + 0.5 * std::hypot(double(w_), double(h_)));
}

double FrameRenderer::Vignette(double x, double y) const { return 1.0 - o_.vignetting * VignettingRadius2(cam_, x, y); }

PsfShape FrameRenderer::ShapeAt(double x, double y) const {
  PsfShape p = shape0_;
  if (varying_sigma_) {
    const double u = VignettingRadius2(cam_, x, y);  // the vignetting's radial scale as well
    p.sigma = std::max(0.5 * std::min(o_.psf_sigma_px, o_.psf_sigma_corner_px),
                       o_.psf_sigma_px + (o_.psf_sigma_corner_px - o_.psf_sigma_px) * u);
  }
  return p;
}

// A direction fixed in inertial space is exp(-[w]x t) v in sensor axes, t from mid-exposure; its image
// through the camera model (distortion included).
std::optional<Vec2> FrameRenderer::PathAt(const Vec3& v_mid, double t) const {
  return cam_.Project(Eigen::AngleAxisd(-rate_rad_s_.norm() * t, rate_rad_s_.normalized()) * v_mid);
}

// The image positions of a moving star at n sub-steps (centres of n equal time slices, at most
// kSmearStepPx apart), and in *smear_px the path's length; empty when still.
std::vector<Vec2> FrameRenderer::SmearPath(const Vec2& p, const Vec3& v_mid, double* smear_px) const {
  std::vector<Vec2> path;
  if (!moving_) return path;
  const auto a = PathAt(v_mid, -0.5 * o_.exposure_s), b = PathAt(v_mid, 0.5 * o_.exposure_s);
  if (!a || !b) return path;
  const int n = std::max(1, static_cast<int>(std::ceil(((*a - p).norm() + (*b - p).norm()) / kSmearStepPx)));
  Vec2 prev = *a;
  for (int k = 0; k <= n; ++k) {
    if (k < n) {
      const auto c = PathAt(v_mid, o_.exposure_s * ((k + 0.5) / n - 0.5));
      path.push_back(c ? *c : p);
    }
    const auto e = PathAt(v_mid, o_.exposure_s * (double(k) / n - 0.5));  // slice edges: path length
    if (e) {
      *smear_px += (*e - prev).norm();
      prev = *e;
    }
  }
  return path;
}

// Draws one star at mid-exposure position p (direction v_mid in sensor axes) and records its truth.
void FrameRenderer::AddStar(StarId id, double mag, const Vec2& p, const Vec3& v_mid) {
  SimStar s;
  s.star_id = id;
  s.mag = mag;
  s.x_px = p.x();
  s.y_px = p.y();
  s.flux_e = o_.mag0_flux_e_per_s * std::pow(10.0, -0.4 * mag) * o_.exposure_s * std::max(0.0, Vignette(p.x(), p.y()));
  s.flux_adu = s.flux_e / o_.gain_e_per_adu;
  const std::vector<Vec2> path = SmearPath(p, v_mid, &s.smear_px);
  // Noise-equivalent area and peak fraction of the local PSF, for the SNR and saturation truth.
  const PsfShape psf = ShapeAt(p.x(), p.y());
  const double nea_px =
      4 * kPi * psf.sigma * psf.sigma * area_factor_ + kPi * o_.defocus_radius_px * o_.defocus_radius_px;
  const double peak_fraction =
      1.0 / (2 * kPi * psf.sigma * psf.sigma * area_factor_ + kPi * o_.defocus_radius_px * o_.defocus_radius_px);
  // The PSF-equivalent Gaussian sigma for the smear's peak / NEA factors (a defocused or elliptical
  // PSF: the Gaussian of the same noise-equivalent area).
  const double sigma_equiv = std::sqrt(nea_px / (4 * kPi));
  const double nea_e = s.smear_px > 0 ? nea_px * SmearNeaFactor(s.smear_px, sigma_equiv) : nea_px;
  const double peak_e = s.smear_px > 0 ? peak_fraction * SmearPeakFactor(s.smear_px, sigma_equiv) : peak_fraction;
  s.snr = s.flux_e / std::sqrt((o_.shot_noise ? s.flux_e : 0.0) + nea_e * var_bg_e2_);
  s.saturated = s.flux_e * peak_e + bg_e_ > o_.full_well_e ||
                (s.flux_e * peak_e + bg_e_) / o_.gain_e_per_adu + o_.bias_adu >= (1 << o_.bit_depth) - 1;
  if (path.empty()) {
    AddPsf(signal_, w_, h_, p.x(), p.y(), o_, psf, s.flux_e);
  } else {
    for (const Vec2& q : path) AddPsf(signal_, w_, h_, q.x(), q.y(), o_, ShapeAt(q.x(), q.y()), s.flux_e / path.size());
  }
  out_.stars.push_back(s);
}

// Every catalog star whose PSF reaches the frame (or, moving, whose smear runs into it).
void FrameRenderer::AddCatalogStars(const StarCatalog& catalog) {
  const Mat3 r_sensor_from_inertial = out_.q_inertial_from_sensor.toRotationMatrix().transpose();
  const double cos_limit = std::cos(0.5 * cam_.FovDiagRad() + 0.01);
  const Vec3 boresight = out_.q_inertial_from_sensor * Vec3::UnitZ();
  const SkyCorrections sky = SkyForSimulation(o_);
  const Vec3 v_observer_m_s = sky.ObserverVelocityMS();
  for (const CatalogStar& cs : catalog.stars) {
    if (cs.mag > o_.mag_max) continue;
    if (cs.unit.dot(boresight) < cos_limit) continue;  // the limit's 0.01 rad margin covers aberration
    const Vec3 v = r_sensor_from_inertial * sky.Apparent(cs, catalog.epoch_year, v_observer_m_s);
    const auto p = cam_.Project(v);
    if (!p || !cam_.InImage(*p, moving_ ? -3 * sigma_max_px_ - smear_margin_px_ : -3 * sigma_max_px_)) continue;
    AddStar(cs.id, cs.mag, *p, v);
  }
}

// False stars: uniform positions 5 px inside the frame, magnitudes from 2 to half a magnitude above the limit.
void FrameRenderer::AddFalseStars(Rng& rng) {
  for (int k = 0; k < o_.false_stars; ++k) {
    const double mag = rng.Uniform(2.0, std::max(2.5, o_.mag_max - 0.5));
    const double y = rng.Uniform(5, h_ - 6);  // y first, in its own statement (see scene_sim.cc)
    const Vec2 p(rng.Uniform(5, w_ - 6), y);
    AddStar(kInvalidStarId, mag, p, moving_ ? cam_.Unproject(p) : Vec3::UnitZ());
  }
}

// Satellite streaks: PSF-blurred lines crossing a good part of the frame.
void FrameRenderer::AddStreaks(Rng& rng) {
  for (int k = 0; k < o_.streaks; ++k) {
    const double x0 = rng.Uniform(0, w_ - 1);
    const double y0 = rng.Uniform(0, h_ - 1);
    const double len = rng.Uniform(0.15, 0.4) * std::min(w_, h_), th = rng.Uniform(0, 2 * kPi);
    SimArtefact a = Track("streak", x0, y0, len, th, w_, h_);
    a.signal_e = o_.streak_flux_e_per_px;
    AddTrack(signal_, w_, h_, a.x0_px, a.y0_px, a.x1_px, a.y1_px, o_.streak_flux_e_per_px, o_.psf_sigma_px);
    out_.artefacts.push_back(a);
  }
}

// Cosmic rays: sharp tracks (charge in the pixels crossed, no optical blur), random length
// (0 = a single-pixel hit) and direction.
void FrameRenderer::AddCosmicRays(Rng& rng) {
  for (int k = 0; k < o_.cosmic_rays; ++k) {
    const double x0 = rng.Uniform(2, w_ - 3);
    const double y0 = rng.Uniform(2, h_ - 3);
    const double len = rng.Uniform(0, o_.cosmic_ray_max_length_px), th = rng.Uniform(0, 2 * kPi);
    SimArtefact a = Track("cosmic_ray", x0, y0, len, th, w_, h_);
    a.signal_e = o_.cosmic_ray_e_per_px * rng.Uniform(0.5, 1.5);
    AddTrack(signal_, w_, h_, a.x0_px, a.y0_px, a.x1_px, a.y1_px, a.signal_e, 0.0);
    out_.artefacts.push_back(a);
  }
}

// Hot pixels: dark rate log-uniform in [min, max]; dead pixels: no response. Both belong to the
// sensor, so they come from their own seed and stay put from frame to frame. Returns the dead-pixel map.
std::vector<uint8_t> FrameRenderer::AddSensorDefects() {
  Rng sensor(0xD5F3C0DEULL + static_cast<uint64_t>(o_.defect_seed));
  std::vector<uint8_t> dead(static_cast<size_t>(w_) * h_, 0);
  for (int k = 0; k < o_.hot_pixels; ++k) {
    const int x = static_cast<int>(sensor.Uniform() * w_), y = static_cast<int>(sensor.Uniform() * h_);
    const double rate =
        o_.hot_pixel_min_e_per_s * std::pow(o_.hot_pixel_max_e_per_s / o_.hot_pixel_min_e_per_s, sensor.Uniform());
    SimArtefact a;
    a.type = "hot_pixel";
    a.x_px = a.x0_px = a.x1_px = x;
    a.y_px = a.y0_px = a.y1_px = y;
    a.signal_e = rate * o_.exposure_s;
    signal_[static_cast<size_t>(y) * w_ + x] += a.signal_e;
    out_.artefacts.push_back(a);
  }
  for (int k = 0; k < o_.dead_pixels; ++k) {
    const int x = static_cast<int>(sensor.Uniform() * w_), y = static_cast<int>(sensor.Uniform() * h_);
    dead[static_cast<size_t>(y) * w_ + x] = 1;
    SimArtefact a;
    a.type = "dead_pixel";
    a.x_px = a.x0_px = a.x1_px = x;
    a.y_px = a.y0_px = a.y1_px = y;
    out_.artefacts.push_back(a);
  }
  return dead;
}

// Detector: background and dark (with vignetting on the sky part), shot noise, full well,
// read noise, gain, bias, quantisation and ADC saturation, into out->image.
void FrameRenderer::ReadOut(const std::vector<uint8_t>& dead, Rng& rng) {
  // The sky gradient: +-background_gradient_e_per_s at the extreme corners along its direction.
  const double gc = std::cos(o_.background_gradient_angle_deg * kDegToRad),
               gs = std::sin(o_.background_gradient_angle_deg * kDegToRad);
  const double g_half_extent = std::abs(gc) * 0.5 * (w_ - 1) + std::abs(gs) * 0.5 * (h_ - 1);
  const bool gradient = o_.background_gradient_e_per_s > 0 && g_half_extent > 0;
  auto sky_at = [&](int x, int y) {
    if (!gradient) return o_.background_e_per_s;
    const double d = ((x - 0.5 * (w_ - 1)) * gc + (y - 0.5 * (h_ - 1)) * gs) / g_half_extent;
    return std::max(0.0, o_.background_e_per_s + o_.background_gradient_e_per_s * d);
  };
  const double adc_max = (1 << o_.bit_depth) - 1;
  out_.image = Image16(w_, h_);
  for (int y = 0; y < h_; ++y) {
    for (int x = 0; x < w_; ++x) {
      const size_t i = static_cast<size_t>(y) * w_ + x;
      double e = signal_[i] + o_.exposure_s * (sky_at(x, y) * Vignette(x, y) + o_.dark_current_e_per_s);
      if (dead[i]) e = 0;
      if (o_.shot_noise) e = rng.Poisson(e);
      e = std::min(e, o_.full_well_e);
      const double noise_e = o_.read_noise_e > 0 ? o_.read_noise_e * rng.Normal() : 0.0;
      double adu = dead[i] ? 0.0 : std::round((e + noise_e) / o_.gain_e_per_adu + o_.bias_adu);
      out_.image.pixels[i] = static_cast<uint16_t>(std::clamp(adu, 0.0, adc_max));
    }
  }
  out_.noise_adu = std::sqrt(var_bg_e2_) / o_.gain_e_per_adu;
}

}  // namespace

SimulatedFrame SimulateFrame(const Camera& cam, const StarCatalog& catalog, const Quat& q_in, const FrameSimOptions& o,
                             uint64_t seed) {
  cam.Check();
  o.Check();
  Rng rng(seed);  // one sequence for the whole frame: the steps' order below is its draw order
  SimulatedFrame out;
  out.seed = seed;
  out.q_inertial_from_sensor = q_in.normalized();
  FrameRenderer frame(cam, o, &out);
  // 1. Stars, catalog and false, smeared along their paths when the camera turns.
  frame.AddCatalogStars(catalog);
  frame.AddFalseStars(rng);
  // 2. Artefacts: satellite streaks, cosmic rays and the sensor's hot and dead pixels.
  frame.AddStreaks(rng);
  frame.AddCosmicRays(rng);
  const std::vector<uint8_t> dead = frame.AddSensorDefects();
  // 3. The detector's readout of the charge image.
  frame.ReadOut(dead, rng);
  return out;
}

Json TruthToJson(const SimulatedFrame& f, const Camera& cam, const FrameSimOptions& o) {
  const auto q = ToWxyz(f.q_inertial_from_sensor);
  const RaDecRoll rdr = RaDecRollFromQuat(f.q_inertial_from_sensor);
  Json j;
  j["q"] = {q[0], q[1], q[2], q[3]};
  j["ra_deg"] = rdr.ra_rad * kRadToDeg;
  j["dec_deg"] = rdr.dec_rad * kRadToDeg;
  j["roll_deg"] = rdr.roll_rad * kRadToDeg;
  j["seed"] = f.seed;
  j["camera"] = CameraToJson(cam);
  j["options"] = FrameSimOptionsToJson(o);
  j["noise_adu"] = f.noise_adu;
  j["background_adu"] = o.bias_adu + (o.background_e_per_s + o.dark_current_e_per_s) * o.exposure_s / o.gain_e_per_adu;
  Json stars = Json::array();
  for (const SimStar& s : f.stars) {
    stars.push_back({{"star_id", s.star_id},
                     {"mag", s.mag},
                     {"x_px", s.x_px},
                     {"y_px", s.y_px},
                     {"smear_px", s.smear_px},
                     {"flux_e", s.flux_e},
                     {"flux_adu", s.flux_adu},
                     {"snr", s.snr},
                     {"saturated", s.saturated},
                     {"false_star", s.star_id == kInvalidStarId}});
  }
  j["stars"] = stars;
  Json arts = Json::array();
  for (const SimArtefact& a : f.artefacts) {
    Json ja = {{"type", a.type}, {"x_px", a.x_px}, {"y_px", a.y_px}};
    if (a.type == "cosmic_ray" || a.type == "streak") {
      ja["x0_px"] = a.x0_px;
      ja["y0_px"] = a.y0_px;
      ja["x1_px"] = a.x1_px;
      ja["y1_px"] = a.y1_px;
    }
    if (a.type != "dead_pixel") ja["signal_e"] = a.signal_e;
    arts.push_back(ja);
  }
  j["artefacts"] = arts;
  return j;
}

}  // namespace ssiu
