// The OpenCV edge: the few functions that draw (overlay, plots, mask PNG) or need OpenCV's geometry
// (solvePnP, blurs) and AprilTag live in libssiu_opencv.so, a module loaded on first use, so that a
// run that never draws does not load OpenCV and its chain (LAPACK, BLAS, gfortran, TBB: ~3 ms at every
// start of `ssiu`, issue 17). Each such function keeps its name and header; in the stage library it
// is a stub that forwards to the module:
//
//   void WritePlotPng(const std::string& path, ...) {
//     static const auto fn = OpenCvEdge<decltype(&WritePlotPng)>("WritePlotPng");
//     fn(path, ...);
//   }
//
// and the module's table (src/groundtest/opencv_edge.cc) maps the name to the real function.
#pragma once

namespace ssiu {

// The module's function `name`, loaded once (thread-safe). Looked for at $SSIU_OPENCV_EDGE, then
// beside the running executable, then where the build put it; std::runtime_error (exit 2) when it
// cannot be loaded or lacks `name`, which is an installation fault.
void* OpenCvEdgeSymbol(const char* name);

template <typename F>
F OpenCvEdge(const char* name) {
  return reinterpret_cast<F>(OpenCvEdgeSymbol(name));
}

}  // namespace ssiu
