// Entry point of `ssiu`: builds the command tree from the registered subcommands and maps errors to
// exit status (conventions.md): 0 done, 1 bad input or usage (one line naming file/field), 2 internal.
#include <iostream>
#include <map>

#include "cli/command.h"
#include "core/error.h"

namespace ssiu::cli {

static std::map<std::string, SetupFn>& Registry() {
  static std::map<std::string, SetupFn> registry;
  return registry;
}

bool RegisterCommand(const std::string& name, SetupFn setup) {
  Registry()[name] = std::move(setup);
  return true;
}

CLI::App* GetOrAddSubcommand(CLI::App& parent, const std::string& name, const std::string& description) {
  for (CLI::App* sub : parent.get_subcommands([](CLI::App*) { return true; })) {
    if (sub->get_name() == name) return sub;
  }
  CLI::App* sub = parent.add_subcommand(name, description);
  sub->require_subcommand(1);
  return sub;
}

}  // namespace ssiu::cli

int main(int argc, char** argv) {
  CLI::App app{"ssiu: strap-down star-inertial unit software (star tracker + four FOGs)", "ssiu"};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "Help for every subcommand");
  for (auto& [name, setup] : ssiu::cli::Registry()) setup(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "ssiu: usage: " << e.what() << " (see ssiu --help)\n";
    return 1;
  } catch (const ssiu::InputError& e) {
    std::cerr << "ssiu: error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "ssiu: internal error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
