// Internal to core: cfitsio loaded on first use. Debian's libcfitsio links libcurl and its TLS and
// Kerberos chain (40 shared libraries, ~6 ms of CPU at every start of `ssiu`, docs/results.md issue
// 17), while most runs never touch a FITS file; so core calls cfitsio through these pointers,
// resolved with dlopen the first time a FITS file is read or written.
#pragma once

#include <fitsio.h>

namespace ssiu {

struct CfitsioApi {
  decltype(&ffdkopn) open_diskfile;
  decltype(&ffinit) create_file;
  decltype(&ffclos) close_file;
  decltype(&ffgky) read_key;
  decltype(&ffghadll) get_hduaddrll;
  decltype(&ffgipr) get_img_param;
  decltype(&ffgiet) get_img_equivtype;
  decltype(&ffgidm) get_img_dim;
  decltype(&ffgisz) get_img_size;
  decltype(&ffcrim) create_img;
  decltype(&ffgpxv) read_pix;
  decltype(&ffppx) write_pix;
};

// The functions, loaded once (thread-safe); std::runtime_error (exit 2) when the library or a
// symbol is missing, which is an installation fault (scripts/setup.sh installs libcfitsio).
const CfitsioApi& Cfitsio();

}  // namespace ssiu
