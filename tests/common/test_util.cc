#include "tests/common/test_util.h"

#include <array>
#include <cstdio>
#include <filesystem>
#include <sys/wait.h>

namespace geodrive {
namespace test {

std::mt19937& Rng() {
  static std::mt19937 rng(kTestSeed);
  return rng;
}

std::string MakeTempDir(const std::string& name) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(GEODRIVE_BINARY_DIR) / "test_tmp" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

std::string RealDataPath(const std::string& relative) {
  return std::string(GEODRIVE_SHARED_DATA_DIR) + "/real/" + relative;
}

std::string GeodriveBinary() { return std::string(GEODRIVE_BINARY_DIR) + "/apps/geodrive"; }

int RunCommand(const std::string& command, std::string* output) {
  const std::string full = command + " 2>&1";
  FILE* pipe = popen(full.c_str(), "r");
  if (!pipe) return -1;
  std::array<char, 4096> buffer;
  std::string text;
  size_t n;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0) text.append(buffer.data(), n);
  const int status = pclose(pipe);
  if (output) *output = text;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

bool PythonHasModule(const std::string& module) {
  return RunCommand(std::string(kDebianPython) + " -c 'import " + module + "'") == 0;
}

}  // namespace test
}  // namespace geodrive
