#include "tests/common/test_util.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

namespace geodrive {
namespace test {

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void WriteFile(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

std::string RunGeodriveEval(const std::string& args, int* rc) {
  std::string out;
  *rc = RunCommand(GeodriveBinary() + " eval " + args, &out);
  return out;
}

int CountLines(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

std::mt19937& Rng() {
  static std::mt19937 rng(kTestSeed);
  return rng;
}

namespace {
std::vector<std::string>& TempDirs() {
  static std::vector<std::string> dirs;
  return dirs;
}
}  // namespace

std::string MakeTempDir(const std::string& name) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(GEODRIVE_BINARY_DIR) / "test_tmp" /
                       (name + "-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  TempDirs().push_back(dir.string());
  return dir.string();
}

int RemoveTempDirs() {
  int removed = 0;
  for (const std::string& dir : TempDirs()) {
    std::error_code ec;
    if (std::filesystem::remove_all(dir, ec) > 0 && !ec) ++removed;
  }
  TempDirs().clear();
  return removed;
}

std::string SharedFixtureDir(
    const std::string& name,
    const std::function<void(const std::string&)>& build) {
  namespace fs = std::filesystem;
  const fs::path root = fs::path(GEODRIVE_BINARY_DIR) / "test_tmp" / "shared";
  fs::create_directories(root);
  const fs::path dir = root / name;
  const std::string lock_path = (root / (name + ".lock")).string();
  const int fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT, 0644);
  if (fd >= 0) ::flock(fd, LOCK_EX);
  // The fixture belongs to this test binary build: key it by the executable's
  // mtime.
  std::error_code ec;
  const auto stamp = std::to_string(
      fs::last_write_time("/proc/self/exe", ec).time_since_epoch().count());
  const fs::path marker = dir / ".complete";
  std::string have;
  if (fs::exists(marker)) {
    std::ifstream in(marker);
    std::getline(in, have);
  }
  if (have != stamp) {
    fs::remove_all(dir);
    fs::create_directories(dir);
    build(dir.string());
    std::ofstream(marker) << stamp << "\n";
  }
  if (fd >= 0) {
    ::flock(fd, LOCK_UN);
    ::close(fd);
  }
  return dir.string();
}

std::string RealDataPath(const std::string& relative) {
  return std::string(GEODRIVE_SHARED_DATA_DIR) + "/real/" + relative;
}

std::string GeodriveBinary() {
  return std::string(GEODRIVE_BINARY_DIR) + "/apps/geodrive";
}

int RunCommand(const std::string& command, std::string* output) {
  const std::string full = command + " 2>&1";
  FILE* pipe = popen(full.c_str(), "r");
  if (!pipe) return -1;
  std::array<char, 4096> buffer;
  std::string text;
  size_t n;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
    text.append(buffer.data(), n);
  const int status = pclose(pipe);
  if (output) *output = text;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

bool PythonHasModule(const std::string& module) {
  return RunCommand(std::string(kDebianPython) + " -c 'import " + module +
                    "'") == 0;
}

}  // namespace test
}  // namespace geodrive
