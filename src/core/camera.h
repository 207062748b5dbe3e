// Camera model (camera.json, ../shared/docs/conventions.md): pinhole plus OpenCV Brown-Conrady
// distortion on normalised coordinates. Pixel (0,0) is the centre of the top-left pixel.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/json.h"
#include "core/types.h"

namespace ssiu {

struct Distortion {
  double k1 = 0, k2 = 0, k3 = 0, p1 = 0, p2 = 0;
  bool IsZero() const { return k1 == 0 && k2 == 0 && k3 == 0 && p1 == 0 && p2 == 0; }
};

struct Camera {
  int width = 1024;
  int height = 1024;
  double focal_length_px = 3510.0;  // fx: 16.6 deg across 1024 px
  // fy (camera.json `focal_length_y_px`, for non-square pixels); 0 = square pixels, fy = fx. Read it
  // through FocalYPx() and scale both with ScaleFocal().
  double focal_length_y_px = 0;
  double cx_px = 511.5;  // principal point; default is the image centre
  double cy_px = 511.5;
  Distortion distortion;
  double gain_e_per_adu = 0;  // optional: 0 = unknown

  // Throws InputError naming `source` and the field when a value is absurd.
  void Check(const std::string& source = "camera") const;

  double FocalXPx() const { return focal_length_px; }
  double FocalYPx() const { return focal_length_y_px > 0 ? focal_length_y_px : focal_length_px; }
  // Angular scale of one pixel: the geometric mean sqrt(fx fy) (a pixel's area in rad^2 is 1 / (fx fy)).
  double FocalMeanPx() const;
  // The smaller of fx, fy: the larger angle per pixel, for tolerances that must hold in both axes.
  double FocalMinPx() const;
  // Multiplies fx and fy by `s` (a common scale; the aspect fy/fx is kept).
  void ScaleFocal(double s);

  // Horizontal / vertical / diagonal field of view (radians), pinhole.
  double FovXRad() const;
  double FovYRad() const;
  double FovDiagRad() const;
  double FovMaxRad() const;  // the larger of FovXRad, FovYRad

  // Normalised coordinates (X/Z, Y/Z) <-> distorted normalised coordinates.
  Vec2 Distort(const Vec2& undistorted) const;
  Vec2 Undistort(const Vec2& distorted) const;  // iterative inverse

  // Direction in the sensor frame -> pixel (nullopt when behind the camera).
  std::optional<Vec2> Project(const Vec3& dir_in_sensor) const;
  // Pixel -> unit direction in the sensor frame.
  Vec3 Unproject(const Vec2& pixel) const;
  bool InImage(const Vec2& pixel, double margin_px = 0) const;
};

// A default camera of `width` x `height` pixels with the given full horizontal FOV.
Camera MakeCamera(int width, int height, double fov_x_deg);

// fov_x_deg_if_no_focal > 0: a camera.json without a focal length is accepted (unknown field of
// view, `ssiu solve --fov-range-deg`) and gets the focal length of this horizontal FOV as a placeholder.
Camera CameraFromJson(const Json& j, const std::string& source, double fov_x_deg_if_no_focal = 0);
Camera LoadCamera(const std::string& path, double fov_x_deg_if_no_focal = 0);
Json CameraToJson(const Camera& c);

// camera.json's optional fields that describe the model under test by `discover frames` beyond the
// geometry (docs/discrepancy.md): its `fitted_camera` writes them, so that the fitted camera goes back in
// as --camera. Every reader of camera.json checks them; `detect`, `solve`, `track` and `calibrate` repair
// the hot pixels before detection and (but `detect`) take the vignetting out of the fluxes before
// identification.
struct CameraExtras {
  double psf_sigma_px = 0;  // model PSF sigma; 0 = not given
  double psf_ellipticity = 0, psf_angle_deg = 0;
  double vignetting = 0;                       // flux factor 1 - vignetting (r / r_corner)^2
  std::vector<std::array<int, 2>> hot_pixels;  // known persistent hot pixels [x, y], repaired before detection
};
// `c` is the camera read from the same object (the image size bounds the hot pixels).
CameraExtras CameraExtrasFromJson(const Json& j, const Camera& c, const std::string& source);
// Adds the fields that are set (psf_* when psf_sigma_px > 0, vignetting when > 0, hot_pixels when any).
void AddCameraExtras(const CameraExtras& e, Json* camera_json);
// The vignetting's radial coordinate u = (r / r_corner)^2: r about the principal point, r_corner the half
// diagonal of the image (the simulator's law; the flux factor is 1 - vignetting u).
double VignettingRadius2(const Camera& c, double x_px, double y_px);
// One entry of heads.json (conventions): {"camera": {camera.json}, "q_body_sensor": [w,x,y,z]}, read
// strictly; `where` names the file and head in errors.
void HeadFromJson(const Json& j, const std::string& where, Camera* camera, Quat* q_body_from_sensor);

}  // namespace ssiu
