// CCSDS Attitude Data Messages (ADM 2.0, CCSDS 504.0-B-2): an attitude history in, AEM or ACM text
// out (KVN or XML, NDM/XML 4.0.0 schemas), and AEM/ACM text in, the same typed history out.
//
// Quaternions (504.0-B-2 sec. 3.2.4 and annex on attitude representations): Q1 Q2 Q3 are the vector
// part, QC the scalar, written in that order (scalar last) in the AEM and the ACM; the quaternion
// rotates frame REF_FRAME_A into REF_FRAME_B, i.e. as a coordinate transformation v_B = A(q) v_A with
// A(q) = (qc^2 - |e|^2) I + 2 e e^T - 2 qc [e x]. ssiu's q_inertial_from_body (Hamilton, scalar first,
// v_inertial = q v_body q*, conventions.md) has R(q) = A(q)^T, so with REF_FRAME_A inertial and
// REF_FRAME_B the body (or sensor) frame the components are the same, scalar moved to the end:
//   ssiu [w, x, y, z]  <->  ADM (Q1, Q2, Q3, QC) = (x, y, z, w).
// A message with REF_FRAME_A the body and REF_FRAME_B inertial holds the inverse (conjugate); ADM 1.0's
// ATTITUDE_DIR = B2A means the same, and its QUATERNION_TYPE = FIRST puts QC first.
// Angular velocity (ANGVEL_X/Y/Z, deg/s): of REF_FRAME_B relative to REF_FRAME_A, in ANGVEL_FRAME
// (ssiu writes the body frame: what a gyro measures). Times: TIME_SYSTEM UTC, ISO 8601 epochs; the ACM's
// data lines hold seconds after EPOCH_TZERO.
#pragma once

#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "core/types.h"

namespace ssiu {

enum class AdmMessage { kAem, kAcm };
inline const char* AdmMessageName(AdmMessage m) { return m == AdmMessage::kAem ? "AEM" : "ACM"; }
inline std::ostream& operator<<(std::ostream& os, AdmMessage v) { return os << AdmMessageName(v); }

// One attitude at t_s (seconds after AttitudeHistory::epoch_utc).
struct AdmState {
  double t_s = 0;
  Quat q_inertial_from_body = Quat::Identity();
  std::optional<Vec3> w_body_rad_s;     // angular velocity of the body relative to inertial, body axes
  std::optional<Vec3> gyro_bias_rad_s;  // estimated gyro bias, body axes
};

// The diagonal of the attitude error covariance at t_s, in the body frame: 3 angles (rad^2), then for
// ANGLE_GYROBIAS 3 gyro biases ((rad/s)^2). 504.0-B-2 ACM COV section; written in deg^2, (deg/s)^2.
struct AdmCovariance {
  double t_s = 0;
  std::vector<double> diagonal;
};

// A sensor of the attitude determination (ACM AD section): name as SANA's spacecraft equipment
// (AST_1 = autonomous star tracker 1, GYRO), its 1-sigma noise per axis and its output rate.
struct AdmSensor {
  int number = 1;
  std::string used;
  std::vector<double> noise_sigma_rad;  // empty = not stated
  double rate_hz = 0;                   // 0 = not stated
};

struct AdmDetermination {
  std::string method = "EKF";  // EKF, QUEST, ...
  std::string source = "SSIU";
  // Gyro noise of the filter (Farrenkopf's model): rate random walk sigma_u (rad/s^1.5) and angle
  // random walk sigma_v (rad/s^0.5); < 0 = not stated.
  double sigma_u_rad_s15 = -1, sigma_v_rad_s05 = -1;
  std::vector<AdmSensor> sensors;
};

// An attitude history as ssiu holds it: one object, one frame pair, SI units, times relative to epoch_utc.
struct AttitudeHistory {
  std::string file;                  // where it was read from ("" when made in memory)
  std::string epoch_utc;             // ISO 8601 UTC of t_s = 0 (required to write)
  std::string object_name = "SSIU";  // OBJECT_NAME
  std::string object_id = "UNKNOWN";
  std::string inertial_frame = "ICRF";   // REF_FRAME_A as written (ICRF, EME2000, ...)
  std::string body_frame = "SC_BODY_1";  // REF_FRAME_B (SC_BODY_1, AST_1, ...)
  std::string basis;                     // ATT_BASIS / COV_BASIS (DETERMINED_GND, SIMULATED); "" = none
  std::vector<std::string> comments;
  std::vector<AdmState> states;  // time order
  std::string cov_type;          // "", "ANGLE" or "ANGLE_GYROBIAS"
  std::vector<AdmCovariance> covariances;
  std::optional<AdmDetermination> determination;
  // When read: the message type, its version ("1.0", "2.0") and the time system it stated.
  AdmMessage message = AdmMessage::kAem;
  std::string version, time_system = "UTC";

  bool has_rates() const;  // every state has w_body_rad_s
  bool has_bias() const;   // every state has gyro_bias_rad_s
};

// The message text. XML (NDM/XML 4.0.0, unqualified) or KVN. `creation_utc` "" = now.
// InputError for a history that cannot be written (no epoch, no state, times out of order).
std::string FormatAdm(const AttitudeHistory& h, AdmMessage message, bool xml, const std::string& creation_utc = "");
// Writes `path` atomically: XML when the name ends in .xml (any case), else KVN.
void WriteAdmFile(const std::string& path, const AttitudeHistory& h, AdmMessage message);

// Reads an AEM or ACM (KVN or XML; an NDM/XML container: its first AEM or ACM) into a history:
// AEM quaternion segments (QUATERNION, QUATERNION/ANGVEL, QUATERNION/DERIVATIVE; ADM 1.0 also
// QUATERNION/RATE and QUATERNION_TYPE, ATTITUDE_DIR), all joined in time order; ACM's first quaternion
// ATT block, its COV blocks and AD section. `epoch_utc` "" = the ACM's EPOCH_TZERO or the AEM's first
// epoch. InputError "FILE:LINE: KEYWORD: what" on anything else (other attitude types, a frame pair
// with no inertial frame, an unknown keyword, a malformed number or epoch, ADM 1.0 XML).
AttitudeHistory ParseAdm(const std::string& text, const std::string& file, const std::string& epoch_utc = "");
AttitudeHistory ReadAdmFile(const std::string& path, const std::string& epoch_utc = "");

// True when the file's first non-blank text is a CCSDS KVN version line (CCSDS_..._VERS) or XML.
bool LooksLikeAdm(const std::string& path);

// Seconds from `from_utc` to the epoch `text` of time system `time_system` (UTC, TAI, TT, GPS):
// "YYYY-MM-DDThh:mm:ss[.f][Z]" or "YYYY-DDDThh:mm:ss[.f]". InputError naming `where`.
double AdmSecondsSince(const std::string& text, const std::string& time_system, const std::string& from_utc,
                       const std::string& where);
// The UTC epoch `t_s` seconds after `epoch_utc`, "YYYY-MM-DDThh:mm:ss.ffffff".
std::string AdmEpoch(const std::string& epoch_utc, double t_s);

}  // namespace ssiu
