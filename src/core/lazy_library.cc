#include "core/lazy_library.h"

#include <dlfcn.h>

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

}  // namespace ssiu::internal
