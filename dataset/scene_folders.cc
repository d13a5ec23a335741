#include "dataset/scene_folders.h"

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "geometry/util/input_file.h"
#include "geometry/util/json_fields.h"
#include "geometry/util/status.h"

namespace geodrive {

namespace fs = std::filesystem;

SceneFolders::SceneFolders(std::string root,
                           const std::string& mapping_file,
                           std::string marker)
    : root_(std::move(root)),
      mapping_file_(mapping_file),
      marker_(std::move(marker)) {
  if (mapping_file.empty()) return;
  InputFileStream in(mapping_file);
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string where = mapping_file + ":" + std::to_string(number);
    if (line[first] == '{') {  // clips.jsonl of `geodrive clips`
      nlohmann::json j;
      try {
        j = internal::ParseJson(line, where);
        const std::string id = j.at("clip_id").get<std::string>();
        const int64_t index =
            internal::JsonInt(where, j.at("index"), "index", 0, 999999);
        GEODRIVE_CHECK_INPUT(index >= 0, where, ": negative index");
        char name[32];
        std::snprintf(name, sizeof(name), "sample_%06lld",
                      static_cast<long long>(index));
        folder_of_clip_[id] = name;
      } catch (const nlohmann::json::exception& e) {
        ThrowInputError(where, "not a clips.jsonl line (", e.what(), ")");
      }
      continue;
    }
    std::istringstream fields(line);
    std::string folder, clip, extra;
    GEODRIVE_CHECK_INPUT(
        static_cast<bool>(fields >> folder >> clip) && !(fields >> extra),
        where, ": expected '<folder name> <clip id>'");
    GEODRIVE_CHECK_INPUT(
        folder.find("..") == std::string::npos && folder.front() != '/', where,
        ": folder '", folder, "' must be a name inside the root");
    folder_of_clip_[clip] = folder;
  }
}

bool SceneFolders::Usable(const std::string& dir) const {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return false;
  return marker_.empty() || fs::exists(fs::path(dir) / marker_, ec);
}

namespace {
bool IsDirectory(const std::string& dir) {
  std::error_code ec;
  return fs::is_directory(dir, ec);
}
}  // namespace

std::optional<std::string> SceneFolders::Find(
    const std::string& clip_id) const {
  std::vector<std::string> names = {clip_id};
  const auto it = folder_of_clip_.find(clip_id);
  if (it != folder_of_clip_.end()) names.push_back(it->second);
  for (const std::string& name : names) {
    // A folder that exists is the clip's (a broken one is then a per-clip
    // failure, not a skip), unless only its reconstruction/ holds the marker.
    const std::string dir = root_ + "/" + name;
    if (!Usable(dir) && Usable(dir + "/reconstruction"))
      return dir + "/reconstruction";
    if (IsDirectory(dir)) return dir;
  }
  return std::nullopt;
}

std::string SceneFolders::Describe() const {
  std::ostringstream os;
  os << root_ << "/{<clip_id>,<clip_id>/reconstruction}";
  if (!mapping_file_.empty())
    os << " and " << folder_of_clip_.size() << " mapped folder name(s) from "
       << mapping_file_;
  return os.str();
}

}  // namespace geodrive
