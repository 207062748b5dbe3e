#include "core/heads.h"

#include "core/error.h"

namespace ssiu {

std::vector<OpticalHead> HeadsFromJson(const Json& list, const std::string& file, const std::string& field) {
  const std::string where = field.empty() ? file : file + ": field '" + field + "'";
  if (!list.is_array()) throw InputError(where, "must be a list of 1 to 3 heads {camera, q_body_sensor}");
  if (list.empty() || list.size() > static_cast<size_t>(kMaxHeads)) {
    throw InputError(where, std::to_string(list.size()) + " heads given, the unit has 1 to 3");
  }
  std::vector<OpticalHead> heads(list.size());
  for (size_t h = 0; h < list.size(); ++h) {
    const std::string what = file + ": " + field + "[" + std::to_string(h) + "]";
    if (!list[h].is_object()) throw InputError(what, "must be an object {camera, q_body_sensor}");
    HeadFromJson(list[h], what, &heads[h].camera, &heads[h].q_body_from_sensor);
    heads[h].extras = CameraExtrasFromJson(list[h].at("camera"), heads[h].camera, what + ".camera");
  }
  return heads;
}

std::vector<OpticalHead> ReadHeadsFile(const std::string& path) { return HeadsFromJson(ReadJsonFile(path), path); }

}  // namespace ssiu
