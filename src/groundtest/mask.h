// Star-sky mask for a collimator ground test (`ssiu groundtest mask`): the plate that, at the focal
// plane of a collimator of focal length F, shows the star tracker the sky of a design attitude.
//
//   Mask m = DesignMask(camera, solver_catalog.stars, QuatFromRaDecRoll(ra, dec, roll), MaskOptions{});
//   SaveMask(m, "out/mask.json"); WriteMaskSvg(m, "out/mask.svg"); WriteMaskPng(m, "out/mask.png", 600);
//
// Plate frame P (mm): origin on the collimator axis, x right and y down as seen from the collimator
// lens (the same axes as the tracker's image when it looks into the collimator), z away from the lens.
// A hole at (x, y) becomes a star at infinity in the direction (x, y, F) / |(x, y, F)| of the mask
// frame M, whose axes are those of a tracker sensor frame aligned with the collimator. The design
// attitude q_design is the tracker attitude (sensor -> inertial) when the sensor frame equals M, so
// a hole's star direction is q_design * (x, y, F)/|.|: the mask is the gnomonic projection of the
// sky scaled by F. The tracker's own lens distortion needs no compensation on the plate (the holes
// are true directions; the tracker's camera model removes its distortion).
// Around the star field the plate carries AprilTag tag36h11 fiducials at known positions, so that
// an auxiliary camera can measure the plate's pose (reference.h).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/catalog.h"
#include "core/json.h"
#include "core/types.h"

namespace ssiu {

struct MaskOptions {
  double collimator_focal_mm = 500.0;
  double mag_max = 0.0;     // faintest star drilled; 0 = all stars given
  double margin_deg = 2.0;  // field beyond the tracker's FOV on each side (stand motion)
  // Hole diameters are graded so that the transmitted flux (hole area) follows the magnitude:
  // d = d_min * 10^(0.2 (mag_faint - mag)), capped at d_max (brighter stars are clamped). 0 = from the
  // tracker pixel's footprint at the collimator focus, p = F / f_px: d_min = 0.2 p, d_max = 2 p.
  double hole_min_diameter_mm = 0.0;
  double hole_max_diameter_mm = 0.0;
  double tag_size_mm = 0.0;  // black square side of a fiducial; 0 = 12% of the field width
  int first_tag_id = 0;      // tags first_tag_id .. first_tag_id + 7
  // Pre-distort the holes for a tracker that does not model its lens distortion (--predistort): each
  // star goes where a distortion-free camera of the same focal length would image it. Off by
  // default: the holes are true directions, and a tracker with a calibrated distortion model sees
  // the real sky's picture (its model removes the lens distortion when it solves).
  bool compensate_distortion = false;
  void Check() const;  // throws InputError naming the field
};

struct MaskHole {
  StarId star_id = kInvalidStarId;
  double mag = 0;             // catalog magnitude
  double mag_effective = 0;   // magnitude the hole's area reproduces (differs when clamped)
  double x_mm = 0, y_mm = 0;  // plate frame
  double diameter_mm = 0;
};

struct MaskTag {
  int id = 0;                 // tag36h11 code index
  double x_mm = 0, y_mm = 0;  // centre
  double size_mm = 0;         // black square side (AprilTag's "tag size")
  // Corners in the order libapriltag reports them (apriltag_detection_t::p): tag coordinates
  // (-1,+1), (+1,+1), (+1,-1), (-1,-1), x along the plate's x, y along the plate's y.
  std::array<Vec2, 4> Corners() const;
};

struct Mask {
  Camera camera;  // the tracker the mask was designed for
  double collimator_focal_mm = 0;
  Quat q_design = Quat::Identity();  // inertial <- mask frame M
  double ra_deg = 0, dec_deg = 0, roll_deg = 0;
  double field_half_x_mm = 0, field_half_y_mm = 0;  // star field (FOV + margin)
  double plate_half_mm = 0;                         // the plate is a square of side 2 * plate_half_mm
  double mag_faint = 0;                             // magnitude of a d_min hole
  double hole_min_diameter_mm = 0, hole_max_diameter_mm = 0;
  std::string tag_family = "tag36h11";
  bool distortion_compensated = false;  // MaskOptions::compensate_distortion
  std::vector<MaskHole> holes;          // brightest first
  std::vector<MaskTag> tags;
  int clamped_holes = 0;  // holes held at d_max

  // Star direction of a plate point in the mask frame M (unit vector).
  Vec3 DirectionOf(double x_mm, double y_mm) const;
};

Mask DesignMask(const Camera& camera, StarSpan stars, const Quat& q_design,
                const MaskOptions& options);

Json MaskToJson(const Mask& m);
// InputError naming `source` and the field for a malformed mask file.
Mask MaskFromJson(const Json& j, const std::string& source);
Mask LoadMask(const std::string& path);
void SaveMask(const Mask& m, const std::string& path);

// Throws InputError (naming `mask_file`) unless the mask was designed for this camera (size, focal
// length within 0.1%, principal point within 0.5 px).
void CheckMaskCamera(const Mask& m, const Camera& camera, const std::string& mask_file);

// Plate drawing as seen from the collimator lens: opaque plate black, holes white, fiducials black
// on white. SVG in mm (exact hole diameters); PNG at `dpi` dots per inch (8-bit grey, the DPI also in
// the PNG's pHYs chunk, so that it prints at 1:1).
void WriteMaskSvg(const Mask& m, const std::string& path);
void WriteMaskPng(const Mask& m, const std::string& path, double dpi);

// The fiducial bit pattern of a tag36h11 code, total_width x total_width cells (white ring, black
// border, data bits), 0 black / 255 white, from libapriltag's family tables.
std::vector<uint8_t> TagPattern(const std::string& family, int id, int* total_width_cells);

}  // namespace ssiu
