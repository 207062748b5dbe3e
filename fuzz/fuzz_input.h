// Shared by the libFuzzer harnesses: ssiu's readers take file names (as the CLI gives them), so each
// input is written to a per-process file first. Bad input must end as an InputError (exit 1 in the
// CLI); any other exception, crash or sanitizer report is a finding.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace ssiu::fuzz {

// Writes the input to one file per process (under $TMPDIR or /tmp) and returns its name.
inline const std::string& InputFile(const uint8_t* data, size_t size, const char* suffix = "") {
  static const std::string path = [&] {
    const char* tmp = std::getenv("TMPDIR");
    return std::string(tmp && *tmp ? tmp : "/tmp") + "/ssiu_fuzz_" + std::to_string(::getpid()) + suffix;
  }();
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) std::abort();
  if (size > 0 && std::fwrite(data, 1, size, f) != size) std::abort();
  std::fclose(f);
  return path;
}

}  // namespace ssiu::fuzz
