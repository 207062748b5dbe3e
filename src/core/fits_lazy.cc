#include "core/fits_lazy.h"

#include <dlfcn.h>

#include <mutex>
#include <stdexcept>
#include <string>

namespace ssiu {
namespace {

template <typename F>
void Resolve(void* lib, const char* name, F* fn) {
  *fn = reinterpret_cast<F>(dlsym(lib, name));
  if (!*fn) throw std::runtime_error(std::string("cfitsio: symbol ") + name + " missing in " + SSIU_CFITSIO_SONAME);
}

CfitsioApi Load() {
  void* lib = dlopen(SSIU_CFITSIO_SONAME, RTLD_NOW | RTLD_LOCAL);  // kept loaded until exit
  if (!lib) throw std::runtime_error(std::string("cannot load ") + SSIU_CFITSIO_SONAME + " (FITS support): " + dlerror());
  CfitsioApi a{};
  Resolve(lib, "ffdkopn", &a.open_diskfile);
  Resolve(lib, "ffinit", &a.create_file);
  Resolve(lib, "ffclos", &a.close_file);
  Resolve(lib, "ffgky", &a.read_key);
  Resolve(lib, "ffghadll", &a.get_hduaddrll);
  Resolve(lib, "ffgipr", &a.get_img_param);
  Resolve(lib, "ffgiet", &a.get_img_equivtype);
  Resolve(lib, "ffgidm", &a.get_img_dim);
  Resolve(lib, "ffgisz", &a.get_img_size);
  Resolve(lib, "ffcrim", &a.create_img);
  Resolve(lib, "ffgpxv", &a.read_pix);
  Resolve(lib, "ffppx", &a.write_pix);
  return a;
}

}  // namespace

const CfitsioApi& Cfitsio() {
  static const CfitsioApi api = Load();  // C++11: initialised once, thread-safe; retried if it threw
  return api;
}

}  // namespace ssiu
