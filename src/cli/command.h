// The `ssiu` program: one file per subcommand, each registering itself here. A subcommand only
// parses flags, calls the library and writes results; all logic lives in the stage libraries.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>

namespace ssiu::cli {

using SetupFn = std::function<void(CLI::App& root)>;

// Registers a subcommand's setup function (called once when the program starts).
bool RegisterCommand(const std::string& name, SetupFn setup);
// Calls every registered setup function on `root` (in name order).
void SetUpCommands(CLI::App& root);

// The subcommand `name` of `parent`, or nullptr.
CLI::App* FindSubcommand(CLI::App& parent, const std::string& name);
// The subcommand `name` of `parent`, created with `description` if it does not exist yet
// (so that `simulate frame` and `simulate gyro` can live in different files).
CLI::App* GetOrAddSubcommand(CLI::App& parent, const std::string& name, const std::string& description);

}  // namespace ssiu::cli

// In a subcommand's .cc: SSIU_REGISTER_COMMAND(detect, [](CLI::App& root) { ... });
#define SSIU_REGISTER_COMMAND(id, ...) \
  static const bool ssiu_registered_##id = ::ssiu::cli::RegisterCommand(#id, __VA_ARGS__)
