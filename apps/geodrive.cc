// The `geodrive` command-line tool: one binary, one subcommand per task
// (apps/*_command.cc, registered in the shared registry of apps/cli/cli.h).
//
// Start-up: the executable holds only the light commands (`info`)
// and links only light libraries. Every other command lives in the plugin
// libgeodrive-commands.so (apps/commands_plugin.cc), loaded when one of them
// runs (or for --help, which lists them all): `geodrive --version` and
// `geodrive info FILE` never load FFmpeg, PCL, Ceres or OpenCV's codecs.

#include <glog/logging.h>

#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "apps/cli/cli.h"
#include "geodrive_version.h"
#include "geometry/util/memory.h"

int main(int argc, char** argv) {
  using namespace geodrive;
  ConfigureAllocatorForThroughput();  // geometry/util/memory.h
  google::InitGoogleLogging(argv[0]);
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = 1;  // warnings and errors only
#ifndef GEODRIVE_COMMANDS_BUILT_IN  // sanitizer builds: apps/CMakeLists.txt
  const std::vector<std::string> builtin_commands = {"info"};
  if (CommandLineNeedsPlugin(argc, argv, builtin_commands)) {
    try {
      AddCommandsFromPlugin("libgeodrive-commands.so", GEODRIVE_VERSION);
    } catch (const std::exception& e) {
      std::cerr << "geodrive: error: " << e.what() << std::endl;
      return kExitInternal;
    }
  }
#endif
  CliProgram program;
  program.name = "geodrive";
  program.description =
      "geodrive " GEODRIVE_VERSION
      " -- geometry toolkit and dataset builder for the GeoDrive "
      "driving world model.\n"
      "Run `geodrive <command> --help` for the options of a command.";
  program.version = std::string("geodrive ") + GEODRIVE_VERSION;
  return RunCommandLine(program, argc, argv);
}
