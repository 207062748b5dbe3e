// The tool commands (allan, discover, fog, groundtest, performance, simulate performance: bench and
// ground work, not the unit's main job) live in the module libssiu_tools.so beside `ssiu`, so that the
// program the main job needs builds without their stages (discover, calibration, groundtest: about
// 40% of the compile; README, first command). `ssiu` loads the module only when its command line
// does not name one of its own commands (or asks for the whole help).
#pragma once

#include <CLI/CLI.hpp>
#include <string>

namespace ssiu::cli {

constexpr char kToolsModule[] = "libssiu_tools.so";
// The module's entry point: adds its commands to `root`; 0, or 1 when `cli11_version` (the program's
// CLI11) is not the module's (a module from another build).
constexpr char kToolsEntry[] = "ssiu_tools_register";
using ToolsEntry = int (*)(CLI::App* root, const char* cli11_version);

// Adds the module's commands to `app` unless the command line names one of the program's own
// commands. Looked for at $SSIU_TOOLS_MODULE when set (only there), else beside the executable, then
// where the build put it. Returns "" when done or not needed; "absent" when no module was found
// (`app` left as it is: a command of the module then fails as unknown, see ToolsAbsentNote); else
// the reason the module could not be used (an installation fault, exit 2).
std::string AddToolCommands(CLI::App& app, int argc, char** argv);

// The note added to a usage error when the module is absent.
std::string ToolsAbsentNote();

}  // namespace ssiu::cli
