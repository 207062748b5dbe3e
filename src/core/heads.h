// The optical heads of a unit (conventions.md, heads.json): one reader for heads.json (`ssiu solve
// --heads`, `ssiu calibrate --heads`) and the "heads" field of a mission config (`ssiu run --config`).
#pragma once

#include <string>
#include <vector>

#include "core/camera.h"
#include "core/json.h"
#include "core/types.h"

namespace ssiu {

// One optical head: its camera and q_body_from_sensor, which rotates vectors from the head's sensor
// frame to the body frame.
struct OpticalHead {
  Camera camera;
  Quat q_body_from_sensor = Quat::Identity();
  CameraExtras extras;  // the head's camera.json fields beyond the geometry (core/camera.h)
};
constexpr int kMaxHeads = 3;

// A list of 1 to kMaxHeads heads {camera, q_body_sensor}, read strictly (HeadFromJson). `file` names
// the file in errors; `field` the key holding the list ("" when the file is the list): errors read
// "FILE: field 'heads': ..." for the list and "FILE: heads[1].camera: ..." for a head.
std::vector<OpticalHead> HeadsFromJson(const Json& list, const std::string& file, const std::string& field = "");
std::vector<OpticalHead> ReadHeadsFile(const std::string& path);

}  // namespace ssiu
