#include "testing/testing.h"

#include <unistd.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "core/error.h"

namespace ssiu::testing {
namespace fs = std::filesystem;

namespace {
// The environment variable when it is set, else the path CMake compiled in.
std::string EnvOr(const char* name, const char* compiled) {
  const char* env = std::getenv(name);
  return env && *env ? std::string(env) : std::string(compiled);
}
}  // namespace

std::string SharedDir() {
  const std::string dir = EnvOr("SSIU_SHARED_DIR", SSIU_TEST_SHARED_DIR);
  std::error_code ec;
  return !dir.empty() && fs::is_directory(dir, ec) ? dir : "";
}

std::string SourceDir() { return EnvOr("SSIU_SOURCE_DIR", SSIU_TEST_SOURCE_DIR); }

std::string SharedData(const std::string& relative) {
  const std::string dir = SharedDir();
  if (dir.empty()) return "";
  const std::string p = dir + "/data/" + relative;
  std::error_code ec;
  return fs::exists(p, ec) ? p : "";
}

std::string SsiuProgram() { return EnvOr("SSIU_BINARY_DIR", SSIU_TEST_BINARY_DIR) + "/ssiu"; }

std::string TempDir(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  // The process id keeps concurrent runs of the same test (two build trees, ctest -j) apart.
  std::string dir = (fs::temp_directory_path() / "ssiu_tests").string() + "/" + std::to_string(::getpid()) + "/" +
                    (info ? std::string(info->test_suite_name()) + "." + info->name() : name) + "." + name;
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir);
  return dir;
}

int Run(const std::string& command, std::string* output) {
  std::string cmd = command + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return -1;
  std::array<char, 4096> buf;
  std::string out;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) out.append(buf.data(), n);
  const int status = pclose(p);
  if (output) *output = out;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

SsiuResult RunSsiu(const std::string& args) {
  SsiuResult r;
  r.status = Run(SsiuProgram() + " " + args, &r.output);
  return r;
}

const StarCatalog& Bsc() {
  static const StarCatalog cat = LoadXplanetBsc(DefaultBscPath());
  return cat;
}

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace ssiu::testing
