#pragma once
// Subcommand registry of the `geodrive` binary. Each apps/<name>_command.cc registers itself:
//
//   GEODRIVE_REGISTER_COMMAND(info, "Print what a file is", SetupInfo);
//
// where `SetupInfo(CLI::App& sub)` adds options to `sub` and returns the function that runs the
// command (returning the exit code). Exit codes: 0 ok, 1 internal failure, 2 bad arguments or bad
// input (InputError), 3 completed with failures (batch jobs).

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

namespace geodrive {

constexpr int kExitOk = 0;
constexpr int kExitInternal = 1;
constexpr int kExitBadInput = 2;
constexpr int kExitCompletedWithFailures = 3;

using CommandRunner = std::function<int()>;
using CommandSetup = std::function<CommandRunner(CLI::App&)>;

struct CommandSpec {
  std::string name;
  std::string description;
  CommandSetup setup;
};

std::vector<CommandSpec>& CommandRegistry();

struct CommandRegistrar {
  CommandRegistrar(const std::string& name, const std::string& description, CommandSetup setup) {
    CommandRegistry().push_back({name, description, std::move(setup)});
  }
};

}  // namespace geodrive

#define GEODRIVE_REGISTER_COMMAND(id, name, description, setup) \
  static ::geodrive::CommandRegistrar geodrive_command_registrar_##id(name, description, setup)
