#include "groundtest/apriltag_family.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagStandard41h12.h>

namespace ssiu::groundtest_internal {

void FamilyDeleter::operator()(apriltag_family* f) const {
  if (f == nullptr) return;
  if (name == "tag36h11")
    tag36h11_destroy(f);
  else if (name == "tag25h9")
    tag25h9_destroy(f);
  else if (name == "tag16h5")
    tag16h5_destroy(f);
  else if (name == "tagStandard41h12")
    tagStandard41h12_destroy(f);
}

FamilyPtr CreateFamily(const std::string& name) {
  apriltag_family* f = nullptr;
  if (name == "tag36h11")
    f = tag36h11_create();
  else if (name == "tag25h9")
    f = tag25h9_create();
  else if (name == "tag16h5")
    f = tag16h5_create();
  else if (name == "tagStandard41h12")
    f = tagStandard41h12_create();
  return FamilyPtr(f, FamilyDeleter{name});
}

const std::vector<std::string>& KnownFamilies() {
  // tag16h5 is left out: its few bits give false detections in any textured photo.
  static const std::vector<std::string> names = {"tag36h11", "tag25h9", "tagStandard41h12"};
  return names;
}

}  // namespace ssiu::groundtest_internal
