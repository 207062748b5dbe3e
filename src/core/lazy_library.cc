#include "core/lazy_library.h"

#include <dlfcn.h>
#include <unistd.h>

#include <stdexcept>
#include <string>

namespace ssiu::internal {

void* OpenLazyLibrary(const char* soname, const char* what) {
  void* lib = dlopen(soname, RTLD_NOW | RTLD_LOCAL);
  if (!lib) throw std::runtime_error(std::string("cannot load ") + soname + " (" + what + "): " + dlerror());
  return lib;
}

void* LazySymbol(void* lib, const char* soname, const char* name) {
  void* fn = dlsym(lib, name);
  if (!fn) throw std::runtime_error(std::string("symbol ") + name + " missing in " + soname);
  return fn;
}

std::string ExecutableDir() {
  char buf[4096];
  const ssize_t n = ::readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (n <= 0) return "";
  const std::string exe(buf, static_cast<size_t>(n));
  return exe.substr(0, exe.find_last_of('/') + 1);
}

}  // namespace ssiu::internal
