#include "core/camera.h"

#include <algorithm>
#include <cmath>

#include "core/attitude.h"
#include "core/error.h"

namespace ssiu {

// The smallest sensor is the detector's smallest image (Detect() needs 16x16 for its background tiles).
void Camera::Check(const std::string& source) const {
  if (width < 16 || width > 65536) throw InputError(source, "width must be 16..65536 pixels");
  if (height < 16 || height > 65536) throw InputError(source, "height must be 16..65536 pixels");
  if (!std::isfinite(focal_length_px) || focal_length_px < 10 || focal_length_px > 1e6) {
    throw InputError(source, "focal_length_px must be 10..1e6 pixels");
  }
  if (!std::isfinite(focal_length_y_px) ||
      (focal_length_y_px != 0 && (focal_length_y_px < 10 || focal_length_y_px > 1e6))) {
    throw InputError(source, "focal_length_y_px must be 10..1e6 pixels");
  }
  if (!std::isfinite(cx_px) || !std::isfinite(cy_px) || cx_px < -0.5 || cy_px < -0.5 || cx_px > width - 0.5 ||
      cy_px > height - 0.5) {
    throw InputError(source, "principal_point must lie inside the image");
  }
  for (double k : {distortion.k1, distortion.k2, distortion.k3, distortion.p1, distortion.p2}) {
    if (!std::isfinite(k) || std::abs(k) > 10)
      throw InputError(source, "distortion coefficients must be finite, |k| <= 10");
  }
  if (!std::isfinite(gain_e_per_adu) || gain_e_per_adu < 0) throw InputError(source, "gain_e_per_adu must be >= 0");
}

double Camera::FocalMeanPx() const { return std::sqrt(focal_length_px * FocalYPx()); }
double Camera::FocalMinPx() const { return std::min(focal_length_px, FocalYPx()); }
void Camera::ScaleFocal(double s) {
  focal_length_px *= s;
  if (focal_length_y_px > 0) focal_length_y_px *= s;
}

double Camera::FovXRad() const { return 2 * std::atan(0.5 * width / focal_length_px); }
double Camera::FovYRad() const { return 2 * std::atan(0.5 * height / FocalYPx()); }
double Camera::FovDiagRad() const {
  return 2 * std::atan(std::hypot(0.5 * width / focal_length_px, 0.5 * height / FocalYPx()));
}
double Camera::FovMaxRad() const { return std::max(FovXRad(), FovYRad()); }

Vec2 Camera::Distort(const Vec2& u) const {
  // OpenCV's Brown-Conrady model (cv::projectPoints documentation).
  const Distortion& d = distortion;
  const double x = u.x(), y = u.y(), r2 = x * x + y * y;
  const double radial = 1 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
  return {x * radial + 2 * d.p1 * x * y + d.p2 * (r2 + 2 * x * x),
          y * radial + d.p1 * (r2 + 2 * y * y) + 2 * d.p2 * x * y};
}

Vec2 Camera::Undistort(const Vec2& dist) const {
  if (distortion.IsZero()) return dist;
  // Newton iterations on Distort(u) = dist with a numerical Jacobian; converges in a few steps for
  // the modest distortions of star-tracker optics.
  Vec2 u = dist;
  for (int it = 0; it < 20; ++it) {
    const Vec2 f = Distort(u) - dist;
    if (f.norm() < 1e-15) break;
    const double h = 1e-7;
    Mat2 jac;
    jac.col(0) = (Distort(u + Vec2(h, 0)) - Distort(u - Vec2(h, 0))) / (2 * h);
    jac.col(1) = (Distort(u + Vec2(0, h)) - Distort(u - Vec2(0, h))) / (2 * h);
    u -= jac.inverse() * f;
  }
  return u;
}

std::optional<Vec2> Camera::Project(const Vec3& v) const {
  if (v.z() <= 1e-9 * v.norm()) return std::nullopt;
  const Vec2 d = Distort(Vec2(v.x() / v.z(), v.y() / v.z()));
  return Vec2(cx_px + focal_length_px * d.x(), cy_px + FocalYPx() * d.y());
}

Vec3 Camera::Unproject(const Vec2& p) const {
  const Vec2 u = Undistort(Vec2((p.x() - cx_px) / focal_length_px, (p.y() - cy_px) / FocalYPx()));
  return Vec3(u.x(), u.y(), 1.0).normalized();
}

bool Camera::InImage(const Vec2& p, double margin) const {
  return p.x() >= -0.5 + margin && p.y() >= -0.5 + margin && p.x() <= width - 0.5 - margin &&
         p.y() <= height - 0.5 - margin;
}

Camera MakeCamera(int width, int height, double fov_x_deg) {
  Camera c;
  c.width = width;
  c.height = height;
  c.focal_length_px = 0.5 * width / std::tan(0.5 * fov_x_deg * kDegToRad);
  c.cx_px = 0.5 * (width - 1);
  c.cy_px = 0.5 * (height - 1);
  return c;
}

Camera CameraFromJson(const Json& j, const std::string& source, double fov_x_deg_if_no_focal) {
  if (!j.is_object()) throw InputError(source, "camera must be a JSON object");
  CheckKeys(j,
            {"width", "height", "focal_length_px", "focal_length_mm", "pixel_pitch_um", "principal_point", "distortion",
             "gain_e_per_adu", "psf_sigma_px", "psf_ellipticity", "psf_angle_deg", "focal_length_y_px", "vignetting",
             "hot_pixels"},
            source);
  Camera c;
  c.width = static_cast<int>(JsonInt(j, "width", 16, 65536, source));
  c.height = static_cast<int>(JsonInt(j, "height", 16, 65536, source));
  if (j.contains("focal_length_px")) {
    if (j.contains("focal_length_mm"))
      throw InputError(source, "give 'focal_length_px' or 'focal_length_mm', not both");
    c.focal_length_px = JsonNumber(j, "focal_length_px", source);
  } else if (j.contains("focal_length_mm")) {
    const double f_mm = JsonNumber(j, "focal_length_mm", source);
    const double pitch_um = JsonNumber(j, "pixel_pitch_um", source);
    if (pitch_um <= 0) throw InputError(source, "field 'pixel_pitch_um' must be > 0");
    c.focal_length_px = f_mm * 1000.0 / pitch_um;
  } else if (fov_x_deg_if_no_focal > 0) {
    // Unknown field of view: a placeholder the solver replaces; square pixels (an fy alone has no fx).
    if (j.contains("focal_length_y_px"))
      throw InputError(source,
                       "field 'focal_length_y_px' needs 'focal_length_px' (without a focal length pixels are square)");
    c.focal_length_px = 0.5 * c.width / std::tan(0.5 * fov_x_deg_if_no_focal * kDegToRad);
  } else {
    throw InputError(source, "missing field 'focal_length_px' (or 'focal_length_mm' + 'pixel_pitch_um')");
  }
  if (j.contains("focal_length_y_px")) c.focal_length_y_px = JsonNumber(j, "focal_length_y_px", source);
  c.cx_px = 0.5 * (c.width - 1);
  c.cy_px = 0.5 * (c.height - 1);
  if (j.contains("principal_point")) {
    const std::vector<double> pp = JsonNumbers(j, "principal_point", 2, source);
    c.cx_px = pp[0];
    c.cy_px = pp[1];
  }
  if (j.contains("distortion")) {
    const Json& d = j.at("distortion");
    const std::string what = source + ": distortion";
    CheckKeys(d, {"k1", "k2", "k3", "p1", "p2"}, what);
    c.distortion.k1 = JsonNumberOr(d, "k1", 0, what);
    c.distortion.k2 = JsonNumberOr(d, "k2", 0, what);
    c.distortion.k3 = JsonNumberOr(d, "k3", 0, what);
    c.distortion.p1 = JsonNumberOr(d, "p1", 0, what);
    c.distortion.p2 = JsonNumberOr(d, "p2", 0, what);
  }
  c.gain_e_per_adu = JsonNumberOr(j, "gain_e_per_adu", 0, source);
  c.Check(source);
  CameraExtrasFromJson(j, c, source);  // checked here, used by `discover frames`
  return c;
}

CameraExtras CameraExtrasFromJson(const Json& j, const Camera& c, const std::string& source) {
  CameraExtras e;
  e.psf_sigma_px = JsonNumberOr(j, "psf_sigma_px", 0, source);
  if (!(e.psf_sigma_px >= 0 && e.psf_sigma_px < 50))
    throw InputError(source, "field 'psf_sigma_px' must be in [0, 50)");
  e.psf_ellipticity = JsonNumberOr(j, "psf_ellipticity", 0, source);
  if (!(e.psf_ellipticity >= 0 && e.psf_ellipticity < 1))
    throw InputError(source, "field 'psf_ellipticity' must be in [0, 1)");
  e.psf_angle_deg = JsonNumberOr(j, "psf_angle_deg", 0, source);
  e.vignetting = JsonNumberOr(j, "vignetting", 0, source);
  if (!(e.vignetting >= 0 && e.vignetting < 1)) throw InputError(source, "field 'vignetting' must be in [0, 1)");
  if (j.contains("hot_pixels")) {
    const Json& h = j.at("hot_pixels");
    if (!h.is_array()) throw InputError(source, "field 'hot_pixels' must be a list of [x, y] pixels");
    for (size_t i = 0; i < h.size(); ++i) {
      const std::string what = "hot_pixels[" + std::to_string(i) + "]";
      if (!h[i].is_array() || h[i].size() != 2 || !h[i][0].is_number_integer() || !h[i][1].is_number_integer())
        throw InputError(source, "field '" + what + "' must be [x, y], two integers");
      const int64_t x = h[i][0].get<int64_t>(), y = h[i][1].get<int64_t>();
      if (x < 0 || x >= c.width || y < 0 || y >= c.height)
        throw InputError(source, "field '" + what + "' lies outside the " + std::to_string(c.width) + "x" +
                                     std::to_string(c.height) + " image");
      e.hot_pixels.push_back({static_cast<int>(x), static_cast<int>(y)});
    }
  }
  return e;
}

void AddCameraExtras(const CameraExtras& e, Json* camera_json) {
  Json& j = *camera_json;
  if (e.psf_sigma_px > 0) {
    j["psf_sigma_px"] = e.psf_sigma_px;
    j["psf_ellipticity"] = e.psf_ellipticity;
    j["psf_angle_deg"] = e.psf_angle_deg;
  }
  if (e.vignetting > 0) j["vignetting"] = e.vignetting;
  if (!e.hot_pixels.empty()) {
    j["hot_pixels"] = Json::array();
    for (const auto& p : e.hot_pixels) j["hot_pixels"].push_back({p[0], p[1]});
  }
}

double VignettingRadius2(const Camera& c, double x_px, double y_px) {
  const double rc2 = 0.25 * (static_cast<double>(c.width) * c.width + static_cast<double>(c.height) * c.height);
  const double dx = x_px - c.cx_px, dy = y_px - c.cy_px;
  return (dx * dx + dy * dy) / rc2;
}

void HeadFromJson(const Json& j, const std::string& where, Camera* camera, Quat* q_body_from_sensor) {
  CheckKeys(j, {"camera", "q_body_sensor"}, where);
  if (!j.contains("camera")) throw InputError(where, "missing field 'camera'");
  *camera = CameraFromJson(j.at("camera"), where + ".camera");
  const std::vector<double> q = JsonNumbers(j, "q_body_sensor", 4, where);
  *q_body_from_sensor = FromWxyz(q[0], q[1], q[2], q[3], (where + ": q_body_sensor").c_str());
}

Camera LoadCamera(const std::string& path, double fov_x_deg_if_no_focal) {
  return CameraFromJson(ReadJsonFile(path), path, fov_x_deg_if_no_focal);
}

Json CameraToJson(const Camera& c) {
  Json j = {{"width", c.width},
            {"height", c.height},
            {"focal_length_px", c.focal_length_px},
            {"principal_point", {c.cx_px, c.cy_px}},
            {"distortion",
             {{"k1", c.distortion.k1},
              {"k2", c.distortion.k2},
              {"k3", c.distortion.k3},
              {"p1", c.distortion.p1},
              {"p2", c.distortion.p2}}}};
  if (c.focal_length_y_px > 0) j["focal_length_y_px"] = c.focal_length_y_px;
  if (c.gain_e_per_adu > 0) j["gain_e_per_adu"] = c.gain_e_per_adu;
  return j;
}

}  // namespace ssiu
