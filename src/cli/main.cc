// Entry point of `ssiu`: builds the command tree from the registered subcommands (and those of the
// tools module when the command line needs it, cli/tools_module.h) and maps errors to exit status
// (conventions.md): 0 done, 1 bad input or usage (one line naming file/field), 2 internal.
#include <iostream>

#include "cli/command.h"
#include "cli/tools_module.h"
#include "core/error.h"

int main(int argc, char** argv) {
  CLI::App app{"ssiu: strap-down star-inertial unit software (star tracker + four FOGs)", "ssiu"};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "Help for every subcommand");
  ssiu::cli::SetUpCommands(app);
  const std::string tools = ssiu::cli::AddToolCommands(app, argc, argv);
  if (!tools.empty() && tools != "absent") {
    std::cerr << "ssiu: error: " << tools << "\n";
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "ssiu: usage: " << e.what() << (tools == "absent" ? ssiu::cli::ToolsAbsentNote() : "")
              << " (see ssiu --help)\n";
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
