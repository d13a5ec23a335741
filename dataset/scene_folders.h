#pragma once
// Where a clip's input folder is under a per-clip root (the MonST3R folders of
// `build-dataset --monst3r ROOT`, or any path-based scene source's), in the
// layouts users really have:
//   ROOT/<clip_id>/                  `demo.py --seq_name <clip_id>`
//   ROOT/<clip_id>/reconstruction/   GeoDrive's prepare_data_monst3r.py
//   ROOT/sample_%06d/[reconstruction/]  GeoDrive's upstream numbering,
//                                    through a mapping (below)
//   ROOT/<name>/[reconstruction/]    any name, through a mapping
// A mapping file is either the clips.jsonl of `geodrive clips` (clip_id and
// index -> sample_%06d) or a text file of "<folder name> <clip id>" lines
// ('#' comments). An existing folder is the clip's; its reconstruction/
// subfolder is taken instead when only that one holds `marker`
// (pred_traj.txt for MonST3R; empty = none).

#include <map>
#include <optional>
#include <string>

namespace geodrive {

class SceneFolders {
 public:
  // Reads the mapping (if any). Throws InputError naming the mapping file.
  SceneFolders(std::string root,
               const std::string& mapping_file,
               std::string marker);
  // The folder of `clip_id`, or nullopt when none of the layouts has it.
  std::optional<std::string> Find(const std::string& clip_id) const;
  // One line for logs: root, mapping, number of mapped names.
  std::string Describe() const;

 private:
  bool Usable(const std::string& dir) const;
  std::string root_, mapping_file_, marker_;
  std::map<std::string, std::string> folder_of_clip_;
};

}  // namespace geodrive
