// Attitude conventions, stated once (../shared/docs/conventions.md):
// - Quaternions are Hamilton, scalar first [w, x, y, z], unit norm, w >= 0 when written out.
// - q_inertial_from_sensor rotates vectors from the sensor frame to the inertial frame (ICRS/J2000):
//   v_inertial = q * v_sensor * conj(q).
// - Sensor frame: +Z boresight, +X along image columns (right), +Y along rows (down).
// - R(ra, dec, roll) = R(ra, dec, 0) * Rz(roll); roll 0 puts image up (-Y) on celestial north, so
//   +X points west.
#pragma once

#include <array>

#include "core/types.h"

namespace ssiu {

// Unit vector of right ascension / declination (radians): (cos d cos a, cos d sin a, sin d).
Vec3 UnitFromRaDec(double ra_rad, double dec_rad);
// Inverse of UnitFromRaDec; ra in [0, 2 pi).
void RaDecFromUnit(const Vec3& u, double* ra_rad, double* dec_rad);

// Attitude (sensor -> inertial) of a boresight at (ra, dec) with the given roll (radians).
Quat QuatFromRaDecRoll(double ra_rad, double dec_rad, double roll_rad);
struct RaDecRoll {
  double ra_rad = 0, dec_rad = 0, roll_rad = 0;
};
// Boresight RA/Dec and roll of an attitude; ra and roll in [0, 2 pi).
RaDecRoll RaDecRollFromQuat(const Quat& q_inertial_from_sensor);

// [w, x, y, z] with w >= 0, normalised: the form ssiu writes.
std::array<double, 4> ToWxyz(const Quat& q);
// From [w, x, y, z]; normalised. Throws InputError (naming `what`) for a zero or non-finite quaternion.
Quat FromWxyz(double w, double x, double y, double z, const char* what = "quaternion");

// Uniformly distributed random rotation from three uniform numbers in [0, 1) (Shoemake 1992).
Quat QuatFromUniform(double u1, double u2, double u3);

// Rotation angle (radians) of q_est * conj(q_true), in [0, pi].
double AttitudeErrorRad(const Quat& q_est, const Quat& q_true);

// The error rotation split into a cross-boresight part (angle between the two boresights) and a
// roll part (rotation about the boresight), both radians, roll signed.
struct AttitudeErrorSplit {
  double total_rad = 0, cross_rad = 0, roll_rad = 0;
};
AttitudeErrorSplit SplitAttitudeError(const Quat& q_est, const Quat& q_true);

}  // namespace ssiu
