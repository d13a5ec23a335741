// The entry point of libgeodrive-commands.so: the `geodrive` commands that
// load heavy libraries (every apps/*_command.cc except info), handed to the
// executable on first use (apps/geodrive.cc, apps/cli/cli.h).

#include "apps/cli/cli.h"
#include "geodrive_version.h"

GEODRIVE_COMMAND_PLUGIN_ENTRY(GEODRIVE_VERSION)
