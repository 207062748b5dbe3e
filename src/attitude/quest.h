// Attitude from verified star matches: QUEST (Shuster & Oh 1981, "Three-axis attitude determination
// from vector observations", J. Guidance Control 4(1)) with Shuster's QUEST measurement model for
// the covariance, and Davenport's q-method as an independent reference for tests.
//
//   AttitudeSolution s = SolveAttitude(identification);   // solved matches -> q, covariance
//
// Covariance: the error rotation delta_theta in the sensor (or body) frame, q_est = q_true * [1, dtheta/2],
// has P = (sum_i sigma_i^-2 (I - b_i b_i^T))^-1 (Shuster 1989, "Maximum likelihood estimation of
// spacecraft attitude", J. Astronaut. Sci. 37(1), eq. 53).
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "core/types.h"
#include "identify/identify.h"

namespace ssiu {

struct WahbaObservation {
  Vec3 b_sensor;            // measured unit vector (sensor or body frame)
  Vec3 r_inertial;          // catalog unit vector
  double sigma_rad = 1e-4;  // 1-sigma angular noise
};

struct AttitudeSolution {
  SolveStatus status = SolveStatus::kNoMatch;  // as the identification's status
  Quat q_inertial_from_sensor = Quat::Identity();
  Mat3 covariance_rad2 = Mat3::Zero();  // of dtheta in the sensor/body frame
  double sigma_cross_rad = 0;           // RMS of the two cross-boresight axes' 1-sigma
  double sigma_roll_rad = 0;            // about +Z (boresight)
  double loss = 0;                      // Wahba loss, sum (1/sigma^2)|b - A r|^2 / 2
  int num_observations = 0;
};

// QUEST: Newton-Raphson on the characteristic equation of Davenport's K from lambda0 = sum(weights),
// with the 180-degree singularity avoided by solving in a frame rotated by pi about an axis.
AttitudeSolution SolveQuest(const std::vector<WahbaObservation>& obs);
// Davenport's q-method: the eigenvector of K with the largest eigenvalue (Eigen's solver).
Quat SolveDavenport(const std::vector<WahbaObservation>& obs);
// Shuster's covariance of the rotation error, sensor frame.
Mat3 QuestCovariance(const std::vector<WahbaObservation>& obs);

// Information matrix (inverse covariance) of the rotation error, sensor frame: Shuster's
// sum sigma^-2 (I - b b^T); with free_scale (the focal length fitted from the same stars) a common
// scale of the pinhole tangent-plane coordinates is a nuisance parameter, marginalised (distortion
// neglected).
Mat3 AttitudeInformation(const std::vector<WahbaObservation>& obs, bool free_scale);

// QUEST on the matches of a solved identification (status copied; no_match gives no attitude); when
// the focal length was fitted (Identification::focal_length_fitted) the covariance includes its
// uncertainty (AttitudeInformation). Reads the matches in place: allocates nothing.
AttitudeSolution SolveAttitude(const Identification& id);

// Several optical heads: matches of head i (sensor frame) rotated to the body frame by
// q_body_from_sensor[i] and fused in one QUEST solution of the body attitude (inertial <- body).
// Heads that did not solve are left out. Before fusing, the heads' own body attitudes are compared
// pairwise: two heads agree when the difference d of their body attitudes (body axes) has
// d^T (P_i + P_j + tol^2 I)^-1 d <= consistency_sigmas^2; the largest set of heads that agree
// pairwise is fused (ties: more matches, then lower false-match probability), the others are
// reported "inconsistent" (a head solved wrongly, or a wrong mount in heads.json).
struct MultiHeadOptions {
  double consistency_sigmas = 6.0;       // chi (3 dof) of the pairwise difference
  double mount_tolerance_arcsec = 60.0;  // unmodelled mount error per axis, added to P_i + P_j
  void Check() const;                    // throws InputError naming the field
  const char* Problem() const;           // Check's message (nullptr: none), without throwing or allocating
};

// How the fusion treated a head: fused, left out as inconsistent (solved, but disagreeing with the
// fused heads), or neither (not solved: its JSON "use" is then its own solve status, e.g. no_match).
enum class HeadUse { kUsed, kInconsistent, kOwnStatus };
// "used", "inconsistent", "own_status".
inline const char* HeadUseName(HeadUse u) {
  return u == HeadUse::kUsed ? "used" : u == HeadUse::kInconsistent ? "inconsistent" : "own_status";
}
inline std::ostream& operator<<(std::ostream& os, HeadUse v) { return os << HeadUseName(v); }
// The JSON's "use": HeadUseName(u), or SolveStatusName(own) for kOwnStatus.
inline const char* HeadUseName(HeadUse u, SolveStatus own) {
  return u == HeadUse::kOwnStatus ? SolveStatusName(own) : HeadUseName(u);
}

struct MultiHeadSolution {
  AttitudeSolution attitude;      // body attitude (q_inertial_from_sensor = inertial <- body), body-axis covariance
  std::vector<HeadUse> head_use;  // per head (HeadUseName with the head's own status for the JSON)
  std::vector<Quat> q_inertial_from_body_per_head;  // each solved head's own body attitude (identity otherwise)
  double false_match_probability = 1.0;             // of the fused heads together: sum of theirs (union bound)
  std::string message;
  // The caller-storage form only: head and mount counts differ or the options are out of range
  // (nothing fused; attitude.status no_match).
  bool input_error = false;
};

MultiHeadSolution SolveMultiHeadChecked(const std::vector<Identification>& heads,
                                        const std::vector<Quat>& q_body_from_sensor,
                                        const MultiHeadOptions& options = {});
// The same into caller-owned `out` (the one implementation): its vectors are refilled (no allocation
// once they have room for heads.size(), e.g. after the first call), no exceptions (bad input:
// out->input_error), and out->message is written only with `diagnostics`. At most 16 solved heads
// take part in the pairwise test (more: none is fused).
void SolveMultiHeadChecked(const std::vector<Identification>& heads, const std::vector<Quat>& q_body_from_sensor,
                           const MultiHeadOptions& options, MultiHeadSolution* out, bool diagnostics);
// The fused attitude of SolveMultiHeadChecked with default options. Allocates nothing (throws
// InputError only when the counts differ).
AttitudeSolution SolveMultiHead(const std::vector<Identification>& heads, const std::vector<Quat>& q_body_from_sensor);

}  // namespace ssiu
