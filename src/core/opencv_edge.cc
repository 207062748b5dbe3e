#include "core/opencv_edge.h"

#include <dlfcn.h>

#include <cstdlib>
#include <stdexcept>
#include <string>

#include "core/lazy_library.h"

namespace ssiu {
namespace {

constexpr char kModule[] = "libssiu_opencv.so";
constexpr char kLookup[] = "ssiu_opencv_edge";  // extern "C" void* (const char* name), the module's table
using Lookup = void* (*)(const char*);

Lookup LoadEdgeModule() {
  std::string tried;
  const char* env = std::getenv("SSIU_OPENCV_EDGE");
  for (const std::string& path :
       {std::string(env && *env ? env : ""), internal::ExecutableDir() + kModule, std::string(SSIU_OPENCV_EDGE_PATH)}) {
    if (path.empty()) continue;
    if (void* lib = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {  // kept loaded until exit
      if (auto fn = reinterpret_cast<Lookup>(dlsym(lib, kLookup))) return fn;
      throw std::runtime_error(path + ": not the ssiu OpenCV edge module (no " + kLookup + ")");
    }
    tried += std::string(tried.empty() ? "" : "; ") + dlerror();
  }
  throw std::runtime_error(std::string("cannot load ") + kModule +
                           " (OpenCV drawing and ground-test geometry; set SSIU_OPENCV_EDGE): " + tried);
}

}  // namespace

void* OpenCvEdgeSymbol(const char* name) {
  static const Lookup lookup = LoadEdgeModule();  // C++11: initialised once, thread-safe; retried if it threw
  void* fn = lookup(name);
  if (!fn)
    throw std::runtime_error(std::string(kModule) + " has no function " + name + " (a module from another build?)");
  return fn;
}

}  // namespace ssiu
