// Camera model (camera.json, ../shared/docs/conventions.md): pinhole plus OpenCV Brown-Conrady
// distortion on normalised coordinates. Pixel (0,0) is the centre of the top-left pixel.
#pragma once

#include <optional>
#include <string>

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
  double focal_length_px = 3510.0;  // 16.6 deg across 1024 px
  double cx_px = 511.5;             // principal point; default is the image centre
  double cy_px = 511.5;
  Distortion distortion;
  double gain_e_per_adu = 0;        // optional: 0 = unknown

  // Throws InputError naming `source` and the field when a value is absurd.
  void Check(const std::string& source = "camera") const;

  // Horizontal / vertical / diagonal field of view (radians), pinhole.
  double FovXRad() const;
  double FovYRad() const;
  double FovDiagRad() const;

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

Camera CameraFromJson(const Json& j, const std::string& source);
Camera LoadCamera(const std::string& path);
Json CameraToJson(const Camera& c);

}  // namespace ssiu
