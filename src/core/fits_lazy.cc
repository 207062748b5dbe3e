#include "core/fits_lazy.h"

#include "core/lazy_library.h"

namespace ssiu {
namespace {

CfitsioApi LoadCfitsio() {
  constexpr const char* so = SSIU_CFITSIO_SONAME;
  void* lib = internal::OpenLazyLibrary(so, "FITS support");
  CfitsioApi a{};
  using internal::Resolve;
  Resolve(lib, so, "ffdkopn", &a.open_diskfile);
  Resolve(lib, so, "ffinit", &a.create_file);
  Resolve(lib, so, "ffclos", &a.close_file);
  Resolve(lib, so, "ffgky", &a.read_key);
  Resolve(lib, so, "ffghadll", &a.get_hduaddrll);
  Resolve(lib, so, "ffgipr", &a.get_img_param);
  Resolve(lib, so, "ffgiet", &a.get_img_equivtype);
  Resolve(lib, so, "ffgidm", &a.get_img_dim);
  Resolve(lib, so, "ffgisz", &a.get_img_size);
  Resolve(lib, so, "ffcrim", &a.create_img);
  Resolve(lib, so, "ffgpxv", &a.read_pix);
  Resolve(lib, so, "ffppx", &a.write_pix);
  return a;
}

}  // namespace

const CfitsioApi& Cfitsio() {
  static const CfitsioApi api = LoadCfitsio();  // C++11: initialised once, thread-safe; retried if it threw
  return api;
}

}  // namespace ssiu
