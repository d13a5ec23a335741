// The `geodrive` command-line tool: one binary, one subcommand per task
// (apps/*_command.cc).

#include <glog/logging.h>

#include <algorithm>
#include <iostream>
#include <map>

#include "apps/command.h"
#include "geodrive_version.h"
#include "geometry/util/memory.h"
#include "geometry/util/status.h"

namespace geodrive {

std::vector<CommandSpec>& CommandRegistry() {
  static std::vector<CommandSpec> registry;
  return registry;
}

}  // namespace geodrive

int main(int argc, char** argv) {
  using namespace geodrive;
  ConfigureAllocatorForThroughput();  // geometry/memory.h
  google::InitGoogleLogging(argv[0]);
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = 1;  // warnings and errors only

  CLI::App app{"geodrive " GEODRIVE_VERSION
               " -- geometry toolkit and dataset builder for the GeoDrive "
               "driving world model.\n"
               "Run `geodrive <command> --help` for the options of a command.",
               "geodrive"};
  app.set_version_flag("--version",
                       std::string("geodrive ") + GEODRIVE_VERSION);
  app.require_subcommand(1);
  app.fallthrough(false);

  auto& registry = CommandRegistry();
  std::sort(registry.begin(), registry.end(),
            [](const CommandSpec& a, const CommandSpec& b) {
              return a.name < b.name;
            });
  std::map<CLI::App*, CommandRunner> runners;
  for (const auto& spec : registry) {
    CLI::App* sub = app.add_subcommand(spec.name, spec.description);
    runners[sub] = spec.setup(*sub);
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line naming the problem, exit 2.
    std::cerr << "geodrive: error: " << e.what() << " (see `geodrive --help`)"
              << std::endl;
    return kExitBadInput;
  }

  for (auto& [sub, runner] : runners) {
    if (!sub->parsed()) continue;
    try {
      return runner();
    } catch (const InputError& e) {
      std::cerr << "geodrive " << sub->get_name() << ": error: " << e.what()
                << std::endl;
      return kExitBadInput;
    } catch (const std::exception& e) {
      std::cerr << "geodrive " << sub->get_name()
                << ": internal error: " << e.what() << std::endl;
      return kExitInternal;
    }
  }
  return kExitInternal;
}
