// libssiu_opencv.so's table (core/opencv_edge.h): the real functions behind the stubs in
// attitude/, analysis/ and groundtest/ opencv_calls.cc, by name.
#include <cstring>

#include "attitude/overlay.h"
#include "calibration/fog_plot.h"
#include "discover/discover_frames.h"
#include "groundtest/mask.h"
#include "groundtest/reference.h"
#include "groundtest/virtual_stand.h"
#include "plot/plot.h"

namespace {

struct Entry {
  const char* name;
  void* fn;
};

template <typename F>
Entry E(const char* name, F fn) {
  return {name, reinterpret_cast<void*>(fn)};
}

}  // namespace

extern "C" __attribute__((visibility("default"))) void* ssiu_opencv_edge(const char* name) {
  using namespace ssiu;
  static const Entry table[] = {
      E("WriteSolveOverlay", &WriteSolveOverlay), E("WritePlotPng", &WritePlotPng),
      E("WriteFogPlotPng", &WriteFogPlotPng),     E("WriteResidualQuiver", &WriteResidualQuiver),
      E("WriteMaskPng", &WriteMaskPng),           E("DetectFiducials", &DetectFiducials),
      E("EstimatePlatePose", &EstimatePlatePose), E("RenderTrackerView", &RenderTrackerView),
      E("RenderAuxScene", &RenderAuxScene),
  };
  for (const Entry& e : table)
    if (std::strcmp(e.name, name) == 0) return e.fn;
  return nullptr;
}
