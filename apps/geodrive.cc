// The `geodrive` command-line tool: one binary, one subcommand per task
// (apps/*_command.cc, registered in the shared registry of apps/cli/cli.h).

#include <glog/logging.h>

#include "apps/cli/cli.h"
#include "geodrive_version.h"
#include "geometry/util/memory.h"

int main(int argc, char** argv) {
  using namespace geodrive;
  ConfigureAllocatorForThroughput();  // geometry/util/memory.h
  google::InitGoogleLogging(argv[0]);
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = 1;  // warnings and errors only
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
