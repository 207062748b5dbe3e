// Entry point of the tools module libssiu_tools.so (cli/tools_module.h): its commands registered
// themselves in its own registry (cli/command.cc) when it was loaded.
#include "cli/tools_module.h"

#include <cstring>

#include "cli/command.h"

extern "C" __attribute__((visibility("default"))) int ssiu_tools_register(CLI::App* root, const char* cli11_version) {
  // CLI::App objects cross the boundary: both sides must have been compiled with the same CLI11.
  if (root == nullptr || cli11_version == nullptr || std::strcmp(cli11_version, CLI11_VERSION) != 0) return 1;
  ssiu::cli::SetUpCommands(*root);
  return 0;
}
