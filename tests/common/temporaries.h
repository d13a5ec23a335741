#pragma once
// Finding temporaries an interrupted or failed job left behind.

#include <filesystem>
#include <string>
#include <vector>

namespace geodrive {
namespace test {

// Paths under `dir` (recursively) whose name marks a temporary: ".tmp"
// anywhere in it, as every temporary of TemporaryPathFor
// (geometry/util/files.h) and the builder's ".tmp-" pair folders have.
inline std::vector<std::string> Temporaries(const std::string& dir) {
  std::vector<std::string> found;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir)) {
    if (e.path().filename().string().find(".tmp") != std::string::npos)
      found.push_back(e.path().string());
  }
  return found;
}

}  // namespace test
}  // namespace geodrive
