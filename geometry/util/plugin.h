#pragma once
// Plugins: the parts of the toolkit that load heavy shared libraries (the
// `geodrive` commands that need FFmpeg, PCL, Ceres; the LibTorch deep metrics)
// are built as shared-library plugins and loaded on first use, so that a
// process that does not use them does not pay their start-up
// (docs/PERFORMANCE.md, "Start-up"). A plugin is found by its file name in:
//   1. $GEODRIVE_PLUGIN_DIR, when set;
//   2. the installed layout: <folder of the running
//   executable>/../lib.../geodrive
//      (the relative path is fixed at configure time from the install dirs);
//   3. the build tree's plugin folder (<build>/lib/geodrive), so that binaries
//      and tests run from the build tree find the plugins built with them.

#include <string>
#include <vector>

namespace geodrive {

// The folders searched, in order (missing ones included).
std::vector<std::string> PluginSearchPath();

// Full path of plugin `file_name` (e.g. "libgeodrive-commands.so"), or "" when
// no folder of PluginSearchPath() has it.
std::string FindPlugin(const std::string& file_name);

// Loads plugin `file_name` (once per process; never unloaded) and returns the
// address of its exported `symbol`. Throws std::runtime_error naming the file
// and the folders searched when it is missing, and dlerror()'s text when it
// cannot be loaded or lacks the symbol.
void* LoadPluginSymbol(const std::string& file_name, const std::string& symbol);

}  // namespace geodrive
