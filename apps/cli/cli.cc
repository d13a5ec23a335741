#include "apps/cli/cli.h"

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <map>
#include <new>
#include <sstream>
#include <stdexcept>

#include "geometry/util/files.h"
#include "geometry/util/output_file.h"
#include "geometry/util/plugin.h"
#include "geometry/util/status.h"

namespace geodrive {

std::vector<CommandSpec>& CommandRegistry() {
  static std::vector<CommandSpec> registry;
  return registry;
}

namespace {

// The page docs/reference/<binary>.md: the top-level --help, then per
// command its description and its --help, exactly as the command prints them
// (CLI11 formats a subcommand's help with its parent's name as prefix).
std::string CommandReferenceMarkdown(const CLI::App& app) {
  const std::string name = app.get_name();
  std::ostringstream os;
  os << "# `" << name << "` command reference\n\n"
     << "Generated from the command registry by `" << name << " "
     << kHelpMarkdownFlag
     << "` (`bash scripts/update_cli_reference.sh` rewrites it); the test "
        "`apps/CliReference` fails when a command's `--help` and this page "
        "differ.\n\n```text\n"
     << app.help() << "```\n";
  for (const CLI::App* sub : app.get_subcommands({})) {
    os << "\n## `" << name << " " << sub->get_name() << "`\n\n"
       << sub->get_description() << "\n\n```text\n"
       << sub->help(name) << "```\n";
  }
  return os.str();
}

constexpr char kOutOfMemoryLine[] =
    "out of memory (the job needs more memory than this process may use: "
    "try a smaller --size, fewer frames or fewer --threads)";

}  // namespace

// The first non-empty line of `text`, trimmed, at most 400 bytes.
std::string FirstLineOf(const std::string& text) {
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(start, end - start);
    const size_t a = line.find_first_not_of(" \t\r");
    if (a != std::string::npos) {
      line = line.substr(a, line.find_last_not_of(" \t\r") - a + 1);
      return line.size() > 400 ? line.substr(0, 400) + "..." : line;
    }
    start = end + 1;
  }
  return "(no message)";
}

// OpenCV ("Insufficient memory", "Failed to allocate"), LibTorch
// ("DefaultCPUAllocator: can't allocate memory", "CUDA out of memory").
bool IsOutOfMemoryMessage(const std::string& text) {
  for (const char* s : {"Insufficient memory", "Failed to allocate",
                        "can't allocate memory", "out of memory"}) {
    if (text.find(s) != std::string::npos) return true;
  }
  return false;
}

int RunCommandLine(const CliProgram& program, int argc, char** argv) {
  CLI::App app{program.description, program.name};
  app.set_version_flag("--version", program.version);
  app.require_subcommand(1);
  app.fallthrough(false);
  if (program.add_global_options) program.add_global_options(app);
  auto& registry = CommandRegistry();
  std::sort(registry.begin(), registry.end(),
            [](const CommandSpec& a, const CommandSpec& b) {
              return a.name < b.name;
            });
  std::map<CLI::App*, CommandRunner> runners;
  try {
    for (const auto& spec : registry) {
      CLI::App* sub = app.add_subcommand(spec.name, spec.description);
      runners[sub] = spec.setup(*sub);
    }
    if (argc == 2 && std::string(argv[1]) == kHelpMarkdownFlag) {
      std::cout << CommandReferenceMarkdown(app);
      return kExitOk;
    }
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line naming the problem, exit 2.
    std::cerr << program.name << ": error: " << e.what() << " (see `"
              << program.name << " --help`)" << std::endl;
    return kExitBadInput;
  } catch (const InputError& e) {
    std::cerr << program.name << ": error: " << e.what() << std::endl;
    return kExitBadInput;
  }
  for (auto& [sub, runner] : runners) {
    if (!sub->parsed()) continue;
    const std::string who = program.name + " " + sub->get_name();
    try {
      if (program.before_run) program.before_run();
      // SIGINT/SIGTERM: temporaries removed, exit 130; SIGXFSZ: a write error.
      InstallInterruptHandlers();
      return runner();
    } catch (const InputError& e) {
      std::cerr << who << ": error: " << e.what() << std::endl;
      return kExitBadInput;
    } catch (const std::filesystem::filesystem_error& e) {
      // A folder or file the command could not create, read or rename
      // (permissions, a full disk, a file where a folder should be): the
      // message names the path(s).
      std::cerr << who << ": error: " << e.what() << std::endl;
      return kExitBadInput;
    } catch (const std::bad_alloc&) {
      std::cerr << who << ": error: " << kOutOfMemoryLine << std::endl;
      return kExitInternal;
    } catch (const std::exception& e) {
      // Library exceptions (LibTorch's c10::Error with its backtrace,
      // OpenCV's cv::Exception, libstdc++'s) print one line: their first.
      // An allocation failure a library reports in its own words is the
      // out-of-memory line.
      const std::string line = FirstLineOf(e.what());
      if (IsOutOfMemoryMessage(e.what())) {
        std::cerr << who << ": error: " << kOutOfMemoryLine << " [" << line
                  << "]" << std::endl;
      } else {
        std::cerr << who << ": internal error: " << line << std::endl;
      }
      return kExitInternal;
    }
  }
  return kExitInternal;
}

void ParseSizeHxW(const std::string& text,
                  const std::string& option,
                  int* height,
                  int* width) {
  const std::string what = option + " '" + text + "'";
  const size_t x = text.find('x');
  GEODRIVE_CHECK_INPUT(x != std::string::npos, what,
                       ": expected HxW (height first), e.g. 480x720");
  try {
    size_t p1 = 0, p2 = 0;
    const long h = std::stol(text.substr(0, x), &p1);
    const long w = std::stol(text.substr(x + 1), &p2);
    GEODRIVE_CHECK_INPUT(p1 == x && p2 == text.size() - x - 1, what,
                         ": expected HxW (height first), e.g. 480x720");
    GEODRIVE_CHECK_INPUT(h >= 1 && w >= 1 && h <= 16384 && w <= 16384, what,
                         ": height and width must be in 1..16384");
    *height = static_cast<int>(h);
    *width = static_cast<int>(w);
  } catch (const std::logic_error&) {
    ThrowInputError(what, "expected HxW (height first), e.g. 480x720");
  }
}

void CheckOutputFileOutsideInput(const std::string& out,
                                 const std::string& input_dir) {
  GEODRIVE_CHECK_INPUT(!out.empty(), "the output path is empty");
  const std::filesystem::path parent =
      std::filesystem::absolute(out).parent_path();
  std::error_code ec;
  GEODRIVE_CHECK_INPUT(
      !std::filesystem::equivalent(parent, input_dir, ec), out,
      ": is inside the input folder ", input_dir,
      " (it would overwrite or mix with its files): write it elsewhere");
  CreateOutputDirectory(parent.string());
}

CLI::Validator ThreadCountValidator() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        long long v = -1;
        size_t used = 0;
        try {
          v = std::stoll(text, &used);
        } catch (const std::logic_error&) {
          used = 0;
        }
        if (used == 0 || used != text.size() || v < 0 || v > kMaxThreads) {
          return "must be an integer in 0.." + std::to_string(kMaxThreads) +
                 " (0 = all cores), got '" + text + "'";
        }
        return "";
      },
      "0.." + std::to_string(kMaxThreads));
}

bool CommandLineNeedsPlugin(int argc,
                            char** argv,
                            const std::vector<std::string>& builtin_commands) {
  bool asks_version = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--version") asks_version = true;
    if (arg.empty() || arg[0] == '-') continue;
    // The first positional argument is the command (neither binary has a
    // top-level option that takes a value).
    return std::find(builtin_commands.begin(), builtin_commands.end(), arg) ==
           builtin_commands.end();
  }
  return !asks_version;
}

void AddCommandsFromPlugin(const std::string& file_name,
                           const std::string& version) {
  const auto entry = reinterpret_cast<CommandPluginEntry>(
      LoadPluginSymbol(file_name, kCommandPluginEntry));
  const CommandPluginInfo info = entry();
  if (info.version == nullptr || version != info.version ||
      info.commands == nullptr) {
    throw std::runtime_error(
        file_name + " is version " + (info.version ? info.version : "?") +
        ", this program " + version +
        ": reinstall, or point GEODRIVE_PLUGIN_DIR at the matching build");
  }
  auto& registry = CommandRegistry();
  registry.insert(registry.end(), info.commands->begin(), info.commands->end());
}

}  // namespace geodrive
