// Helpers shared by ssiu's tests: where the real data is, where the `ssiu` program is, and
// domain matchers that make assertions read like the requirement.
#pragma once

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <string>

// True in the AddressSanitizer builds (scripts/test.sh), where the heaviest simulations run 5-10x slower:
// a test may leave to a lighter one the code both run there.
#if defined(__SANITIZE_ADDRESS__)
#define SSIU_TESTING_UNDER_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SSIU_TESTING_UNDER_SANITIZER 1
#endif
#endif
#ifndef SSIU_TESTING_UNDER_SANITIZER
#define SSIU_TESTING_UNDER_SANITIZER 0
#endif

#include "core/attitude.h"
#include "core/catalog.h"

namespace ssiu::testing {

inline constexpr bool kUnderSanitizer = SSIU_TESTING_UNDER_SANITIZER != 0;

// ../shared ($SSIU_SHARED_DIR, else the path CMake was configured with); empty when absent.
std::string SharedDir();
// The source tree ($SSIU_SOURCE_DIR, else the configured one).
std::string SourceDir();
// Path of a file under shared/data, or "" (and the test should skip) when it is absent.
std::string SharedData(const std::string& relative);
// The built `ssiu` program ($SSIU_BINARY_DIR/ssiu, else the configured build's).
std::string SsiuProgram();
// A fresh temporary directory for one test.
std::string TempDir(const std::string& name);
// Runs a shell command; returns its exit status, stdout+stderr in *output.
int Run(const std::string& command, std::string* output);

// Runs the `ssiu` program with `args`: its exit status and combined output.
struct SsiuResult {
  int status = -1;
  std::string output;
};
SsiuResult RunSsiu(const std::string& args);

// The message of the InputError `f` throws, or "no error".
std::string ErrorOf(const std::function<void()>& f);

// The bundled Bright Star Catalogue (LoadXplanetBsc(DefaultBscPath())), loaded once per test program.
const StarCatalog& Bsc();

}  // namespace ssiu::testing

// Skips the test with a clear message when shared data is missing.
#define SSIU_REQUIRE_SHARED(path_var, relative)                                         \
  const std::string path_var = ::ssiu::testing::SharedData(relative);                   \
  if (path_var.empty()) {                                                               \
    GTEST_SKIP() << "shared data '" << relative << "' not found (../shared is absent)"; \
  }

// Attitude within tol_arcsec of the expected one (rotation angle of q * conj(expected)).
MATCHER_P2(QuaternionNear, expected, tol_arcsec, "") {
  const double err = ::ssiu::AttitudeErrorRad(arg, expected) * ::ssiu::kRadToArcsec;
  *result_listener << "attitude error " << err << " arcsec";
  return err <= tol_arcsec;
}
