#include "geometry/util/plugin.h"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <system_error>

namespace geodrive {
namespace {

namespace fs = std::filesystem;

std::string ExecutableFolder() {
  std::error_code error;
  const fs::path exe = fs::read_symlink("/proc/self/exe", error);
  return error ? std::string() : exe.parent_path().string();
}

}  // namespace

std::vector<std::string> PluginSearchPath() {
  std::vector<std::string> folders;
  if (const char* dir = std::getenv("GEODRIVE_PLUGIN_DIR"); dir && *dir) {
    folders.push_back(dir);
  }
  const std::string exe_folder = ExecutableFolder();
  if (!exe_folder.empty()) {
    folders.push_back((fs::path(exe_folder) / GEODRIVE_PLUGIN_RELATIVE_DIR)
                          .lexically_normal());
  }
  folders.push_back(GEODRIVE_PLUGIN_BUILD_DIR);
  return folders;
}

std::string FindPlugin(const std::string& file_name) {
  for (const std::string& folder : PluginSearchPath()) {
    std::error_code error;
    const fs::path path = fs::path(folder) / file_name;
    if (fs::is_regular_file(path, error)) return path.string();
  }
  return "";
}

void* LoadPluginSymbol(const std::string& file_name,
                       const std::string& symbol) {
  // dlopen/dlerror are not thread-safe together: one loader at a time.
  static std::mutex mutex;
  std::lock_guard<std::mutex> lock(mutex);
  const std::string path = FindPlugin(file_name);
  if (path.empty()) {
    std::string searched;
    for (const std::string& folder : PluginSearchPath()) {
      searched += (searched.empty() ? "" : ", ") + folder;
    }
    throw std::runtime_error("plugin " + file_name + " not found (searched " +
                             searched + "; set GEODRIVE_PLUGIN_DIR)");
  }
  // RTLD_LOCAL: the plugin's own copies of the toolkit's static libraries stay
  // private to it; RTLD_NOW: a missing dependency fails here, not mid-command.
  void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* why = dlerror();
    throw std::runtime_error(
        path + ": cannot load plugin: " + (why ? why : "unknown dlopen error"));
  }
  dlerror();
  void* address = dlsym(handle, symbol.c_str());
  if (address == nullptr) {
    const char* why = dlerror();
    throw std::runtime_error(path + ": not a geodrive plugin (no " + symbol +
                             (why ? std::string(": ") + why : "") + ")");
  }
  return address;
}

}  // namespace geodrive
