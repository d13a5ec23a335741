#pragma once
// What both binaries (`geodrive`, `geodrive-diffusion`) share on the command
// line: one subcommand registry, one error ladder with the exit codes, and
// the parsers of common option values. Each subcommand registers itself:
//
//   GEODRIVE_REGISTER_COMMAND(info, "info", "Print what a file is", SetupInfo);
//
// where `SetupInfo(CLI::App& sub)` adds options to `sub` and returns the
// function that runs the command (returning the exit code).
//
// Exit codes: 0 ok, 1 internal failure, 2 bad arguments or bad input
// (InputError, one line on stderr naming the file and the problem), 3
// completed with failures (batch jobs), 130 interrupted.

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

namespace geodrive {

constexpr int kExitOk = 0;
constexpr int kExitInternal = 1;
constexpr int kExitBadInput = 2;
constexpr int kExitCompletedWithFailures = 3;
constexpr int kExitInterrupted = 130;

using CommandRunner = std::function<int()>;
using CommandSetup = std::function<CommandRunner(CLI::App&)>;

struct CommandSpec {
  std::string name;
  std::string description;
  CommandSetup setup;
};

// The commands registered in this binary (one registry per process).
std::vector<CommandSpec>& CommandRegistry();

struct CommandRegistrar {
  CommandRegistrar(const std::string& name,
                   const std::string& description,
                   CommandSetup setup) {
    CommandRegistry().push_back({name, description, std::move(setup)});
  }
};

// A binary: its name, --help text and version, and optional global options.
struct CliProgram {
  // Binary name as typed ("geodrive").
  std::string name;
  // Top-level --help text.
  std::string description;
  // Printed by --version.
  std::string version;
  // Adds options of the top-level app (e.g. --threads); may be empty.
  std::function<void(CLI::App&)> add_global_options;
  // Runs after parsing, before the command (e.g. thread set-up); may be
  // empty.
  std::function<void()> before_run;
};

// Parses argv against the registered commands (sorted by name) and runs the
// chosen one: the error ladder. --help/--version exit 0; a parse error or an
// InputError or a std::filesystem error (it names the paths) prints one line
// "<name> [<command>]: error: ..." and returns 2; std::bad_alloc prints
// "...: error: out of memory (...)" and returns 1; any other exception
// "...: internal error: ..." and returns 1.
//
// `<name> --help-markdown` (the only argument; not listed in --help) prints
// the command reference page in Markdown instead: the top-level --help and
// every registered command's --help, byte for byte as `<name> <command>
// --help` prints it (docs/reference/<name>.md is this output).
int RunCommandLine(const CliProgram& program, int argc, char** argv);

// The error ladder's one line for a library exception: the first non-empty
// line of its message, trimmed, at most 400 bytes (LibTorch appends a
// backtrace, OpenCV starts with an empty line).
std::string FirstLineOf(const std::string& text);

// True for the allocation failures libraries report in their own words
// (OpenCV's "Insufficient memory" / "Failed to allocate", LibTorch's "can't
// allocate memory", "out of memory"): the ladder prints the out-of-memory
// line for them.
bool IsOutOfMemoryMessage(const std::string& text);

// The hidden flag that prints the command reference (see RunCommandLine).
constexpr char kHelpMarkdownFlag[] = "--help-markdown";

// An image size "HxW" (height first, e.g. 480x720, as every --size of both
// binaries), each in 1..16384. Throws InputError naming `option`.
void ParseSizeHxW(const std::string& text,
                  const std::string& option,
                  int* height,
                  int* width);

// No command writes over its own inputs: throws InputError naming `out` when
// the output file `out` would land inside `input_dir` (the folder a command
// reads, e.g. a MonST3R folder, whose files it could overwrite or mix with).
// Also creates `out`'s folder and checks it is writable
// (CreateOutputDirectory), so an unusable output fails before any work.
void CheckOutputFileOutsideInput(const std::string& out,
                                 const std::string& input_dir);

// The largest --threads any command accepts. OpenMP and std::thread teams
// far beyond the core count only cost memory (libgomp fails to create them
// somewhere above a thousand, with a raw message of its own).
constexpr int kMaxThreads = 256;

// Validator of every --threads option: an integer (the whole string) in
// 0..kMaxThreads, 0 meaning "all cores".
CLI::Validator ThreadCountValidator();

// ---- Commands in a plugin (geometry/util/plugin.h) ----
// A binary may keep its light commands in the executable and its heavy ones
// (those that load FFmpeg, PCL, Ceres...) in a plugin loaded only when one of
// them runs: `geodrive --version` and `geodrive info` then start in a few
// milliseconds. The plugin defines GEODRIVE_COMMAND_PLUGIN_ENTRY() once and
// registers its commands with GEODRIVE_REGISTER_COMMAND as usual.

// What a command plugin hands to the executable.
struct CommandPluginInfo {
  // The plugin's GEODRIVE_VERSION; must equal the executable's.
  const char* version = nullptr;
  // The plugin's registry (its own copy of CommandRegistry()).
  const std::vector<CommandSpec>* commands = nullptr;
};

// The exported entry point's name and type.
constexpr char kCommandPluginEntry[] = "GeodriveCommandPlugin";
using CommandPluginEntry = CommandPluginInfo (*)();

// False when the command line can run without the plugin: its command is one
// of `builtin_commands`, or it names no command and asks for --version.
bool CommandLineNeedsPlugin(int argc,
                            char** argv,
                            const std::vector<std::string>& builtin_commands);

// Loads plugin `file_name` and appends its commands to CommandRegistry().
// Throws std::runtime_error when it is missing, cannot be loaded, or was
// built for another version than `version`.
void AddCommandsFromPlugin(const std::string& file_name,
                           const std::string& version);

}  // namespace geodrive

// Defines the plugin's entry point (in exactly one file of the plugin).
#define GEODRIVE_COMMAND_PLUGIN_ENTRY(version_string)                      \
  extern "C"                                                               \
      __attribute__((visibility("default"))) ::geodrive::CommandPluginInfo \
      GeodriveCommandPlugin() {                                            \
    return {version_string, &::geodrive::CommandRegistry()};               \
  }

#define GEODRIVE_REGISTER_COMMAND(id, name, description, setup)        \
  static ::geodrive::CommandRegistrar geodrive_command_registrar_##id( \
      name, description, setup)
