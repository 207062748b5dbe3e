// The registry of subcommands (cli/command.h). The program and the tools module
// (libssiu_tools.so, cli/tools_module.h) each have their own: a module's setup functions are added
// to the program's command tree by the module's entry point.
#include "cli/command.h"

#include <map>

namespace ssiu::cli {

namespace {

std::map<std::string, SetupFn>& Registry() {
  static std::map<std::string, SetupFn> registry;
  return registry;
}

}  // namespace

bool RegisterCommand(const std::string& name, SetupFn setup) {
  Registry()[name] = std::move(setup);
  return true;
}

void SetUpCommands(CLI::App& root) {
  for (auto& [name, setup] : Registry()) setup(root);
}

CLI::App* FindSubcommand(CLI::App& parent, const std::string& name) {
  for (CLI::App* sub : parent.get_subcommands([](CLI::App*) { return true; })) {
    if (sub->get_name() == name) return sub;
  }
  return nullptr;
}

CLI::App* GetOrAddSubcommand(CLI::App& parent, const std::string& name, const std::string& description) {
  if (CLI::App* sub = FindSubcommand(parent, name)) return sub;
  CLI::App* sub = parent.add_subcommand(name, description);
  sub->require_subcommand(1);
  return sub;
}

}  // namespace ssiu::cli
