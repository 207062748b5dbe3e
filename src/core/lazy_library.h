// Shared libraries loaded on first use (cfitsio, libtiff; the modules beside `ssiu`), so that `ssiu`
// does not load them, and the chains they link, at every start (issue 17; docs/results.md "Fast start").
#pragma once

#include <string>

namespace ssiu::internal {

// dlopen(soname), kept loaded until exit; std::runtime_error naming `what` when it cannot be loaded
// (an installation fault: exit 2).
void* OpenLazyLibrary(const char* soname, const char* what);
// dlsym(lib, name); std::runtime_error when it is missing.
void* LazySymbol(void* lib, const char* soname, const char* name);

// The running executable's directory with a trailing '/' (where its modules sit), "" if unknown.
std::string ExecutableDir();

template <typename F>
void Resolve(void* lib, const char* soname, const char* name, F* fn) {
  *fn = reinterpret_cast<F>(LazySymbol(lib, soname, name));
}

}  // namespace ssiu::internal
