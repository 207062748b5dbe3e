// Internal: libapriltag families by name (libapriltag stays behind this header and the .cc files).
#pragma once

#include <memory>
#include <string>
#include <vector>

struct apriltag_family;

namespace ssiu::groundtest_internal {

struct FamilyDeleter {
  std::string name;
  void operator()(apriltag_family* f) const;
};
using FamilyPtr = std::unique_ptr<apriltag_family, FamilyDeleter>;

// nullptr for an unknown name.
FamilyPtr CreateFamily(const std::string& name);
// The families `reference` tries when no fiducial of the mask's family is found.
const std::vector<std::string>& KnownFamilies();

}  // namespace ssiu::groundtest_internal
