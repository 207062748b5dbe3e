// Loading the tools module (cli/tools_module.h) into `ssiu`.
#include <dlfcn.h>
#include <sys/stat.h>

#include <cstdlib>

#include "cli/command.h"
#include "cli/tools_module.h"
#include "core/lazy_library.h"

namespace ssiu::cli {
namespace {

bool Exists(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0;
}

// The command line names a command of the program's own tree (a leaf), before any flag.
bool ProgramHas(CLI::App& app, int argc, char** argv) {
  CLI::App* node = &app;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.empty() || a[0] == '-') return false;  // e.g. `ssiu --help`, `ssiu simulate --help`: list all
    node = FindSubcommand(*node, a);
    if (node == nullptr) return false;
    if (node->get_subcommands([](CLI::App*) { return true; }).empty()) return true;
  }
  return false;
}

}  // namespace

std::string AddToolCommands(CLI::App& app, int argc, char** argv) {
  if (ProgramHas(app, argc, argv)) return "";
  const char* env = std::getenv("SSIU_TOOLS_MODULE");
  const std::string paths[] = {env && *env ? std::string(env) : internal::ExecutableDir() + kToolsModule,
                               env && *env ? std::string() : std::string(SSIU_TOOLS_MODULE_PATH)};
  for (const std::string& path : paths) {
    if (path.empty() || !Exists(path)) continue;
    void* lib = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);  // kept loaded until exit
    if (lib == nullptr) return std::string("cannot load ") + path + ": " + dlerror();
    auto entry = reinterpret_cast<ToolsEntry>(dlsym(lib, kToolsEntry));
    if (entry == nullptr) return path + ": not the ssiu tools module (no " + kToolsEntry + ")";
    if (entry(&app, CLI11_VERSION) != 0)
      return path + ": built with another CLI11 than this ssiu (a module from another build?)";
    return "";
  }
  return "absent";
}

std::string ToolsAbsentNote() {
  return std::string("; this build has no ") + kToolsModule +
         " (the commands allan, discover, fog, groundtest, performance, simulate performance): "
         "cmake --build build --target ssiu_tools, or scripts/test.sh";
}

}  // namespace ssiu::cli
