// libFuzzer target: the nuScenes JSON tables (dataset/nuscenes.h).
//
// At start-up a small synthetic dataroot (1 scene, 1 s, tables only) is
// written under $TMPDIR. Each input's first byte picks one of the 13 tables
// (modulo 13), the rest of the input replaces that table's file, and the whole
// dataset is loaded and validated (cross-table references included); the table
// is then restored. Seeds (fuzz/corpus/nuscenes_tables/): the 13 valid tables
// (fuzz/make_seeds.py), each behind its selector byte, and tables nested past
// the JSON depth limit (deep-*: 30,000 arrays or 8,000 objects in a field, in a
// matrix row, around the whole table; one level below and above the limit).
// Dictionary: fuzz/dict/nuscenes_tables.dict (JSON tokens, field names).
#include <fstream>
#include <sstream>
#include <vector>

#include "dataset/nuscenes.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "fuzz/fuzz_util.h"

namespace {

const char* const kTables[] = {"attribute",
                               "calibrated_sensor",
                               "category",
                               "ego_pose",
                               "instance",
                               "log",
                               "map",
                               "sample",
                               "sample_annotation",
                               "sample_data",
                               "scene",
                               "sensor",
                               "visibility"};
constexpr int kNumTables = sizeof(kTables) / sizeof(kTables[0]);

struct Dataroot {
  std::string root, version_dir;
  std::vector<std::string> originals;  // each table's valid content
};

Dataroot& Base() {
  static Dataroot base = [] {
    Dataroot d;
    d.root = geodrive::fuzz::InputPath("nuscenes");
    geodrive::SyntheticDatasetOptions options;
    options.num_scenes = 1;
    options.scene_duration_s = 1.0;
    options.tables_only = true;
    geodrive::WriteSyntheticDataset(options, d.root);
    d.version_dir = d.root + "/" + options.version;
    for (const char* table : kTables) {
      std::ifstream in(d.version_dir + "/" + table + ".json", std::ios::binary);
      std::stringstream ss;
      ss << in.rdbuf();
      d.originals.push_back(ss.str());
    }
    return d;
  }();
  return base;
}

void WriteTable(const std::string& path, const char* data, size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(data, static_cast<std::streamsize>(size));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace geodrive;
  if (size == 0) return 0;
  Dataroot& base = Base();
  const int table = data[0] % kNumTables;
  const std::string path = base.version_dir + "/" + kTables[table] + ".json";
  WriteTable(path, reinterpret_cast<const char*>(data + 1), size - 1);
  fuzz::ExpectReturnOrInputError([&] {
    NuscenesOptions options;
    options.dataroot = base.root;
    Nuscenes nusc(options);
  });
  const std::string& original = base.originals[table];
  WriteTable(path, original.data(), original.size());
  return 0;
}
