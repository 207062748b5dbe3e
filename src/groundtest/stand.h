// Geometry of the collimator test stand (docs/ground-test.md, "Frames").
//
//   C  collimator frame: the nominal plate frame P (origin on the collimator axis at the focal plane,
//      x right / y down seen from the lens, z away from the lens).
//   P  the plate as it actually sits: X_C = R_c_from_p X_P + t_c_mm (near identity / zero).
//   M  mask frame: a hole at plate (x, y) is a star in direction (x, y, F)/|.| of M.
//   S  tracker sensor frame. The stand turns the tracker: q_C_from_S = StandRotation(enc) * q_mis,
//      q_mis being the (unknown) stand-to-tracker mounting misalignment.
//
// What the tracker reports is q_design * conj(q_C_from_M) * q_C_from_S, so the reference for a
// picture is q_ref = q_design * conj(q_C_from_M) * StandRotation(enc), and conj(q_ref) * q_est is the
// misalignment (plus noise) in the sensor frame.
#pragma once

#include "core/types.h"
#include "groundtest/mask.h"
#include "inertial/propagate.h"

namespace ssiu {

// Stand encoder angles -> rotation C <- stand plate: azimuth about the collimator's +y (image down)
// axis (positive turns the boresight towards +x), elevation about +x (positive tilts it towards
// image up, -y), rotation about the boresight: R = Ry(az) * Rx(el) * Rz(rot).
Quat StandRotation(double az_rad, double el_rad, double rot_rad);

struct PlatePose {
  Mat3 r_c_from_p = Mat3::Identity();
  Vec3 t_c_mm = Vec3::Zero();
};

// Direction in C of the star shown by plate point (x, y) when the plate sits at `pose`: the chief ray
// from the collimator lens centre (0, 0, -F) to the point.
Vec3 ApparentDirection(const Mask& m, const PlatePose& pose, double x_mm, double y_mm);

// The rotation q_C_from_M that best maps the holes' design directions to their apparent directions
// for a displaced plate (Wahba problem over the holes and tag centres; a lateral shift t moves the
// sky by t / F rad, an in-plane turn is a roll).
Quat MaskRotation(const Mask& m, const PlatePose& pose);

// Rotation vector (rad) of a rotation (shortest, w >= 0); the inverse is inertial/propagate.h's
// QuatFromRotationVector.
Vec3 RotationVector(const Quat& q);

}  // namespace ssiu
