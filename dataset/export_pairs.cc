// `geodrive export` (dataset/build_dataset.h, ExportPairs): other trainers'
// files added to the pairs of a finished build-dataset output, as --export
// would have written them. Each pair's clip is loaded again and its scene
// built and rendered with the pair's own options (meta.json), so that the
// condition is rendered at the trainer's size rather than resized from ours.

#include <filesystem>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include "dataset/build_dataset.h"
#include "dataset/internal/pair_builder.h"
#include "dataset/pairs.h"
#include "dataset/scene_folders.h"
#include "geometry/util/files.h"
#include "geometry/util/output_file.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The build options a pair was made with: its meta.json content options and
// inputs (BuildDatasetOptions::ContentOptionsJson, InputsJson).
BuildDatasetOptions OptionsOfPair(const PairMeta& meta,
                                  const std::string& pair_dir) {
  const std::string what = pair_dir + "/meta.json";
  BuildDatasetOptions o;
  try {
    const json j = json::parse(meta.options_json);
    GEODRIVE_CHECK_INPUT(
        !j.contains("cameras"), what,
        ": a surround-view pair; export a rig with build-dataset --cameras "
        "... --export drivestudio or rds-hq (geodrive export converts "
        "single-camera pairs)");
    const json& in = j.at("inputs");
    o.dataroot = in.at("dataroot").get<std::string>();
    if (in.contains("root")) o.monst3r_root = in["root"].get<std::string>();
    if (in.contains("root_map"))
      o.monst3r_map = in["root_map"].get<std::string>();
    o.version = j.at("version").get<std::string>();
    o.geometry = j.at("geometry").get<std::string>();
    o.preset = ParseRenderPreset(j.at("preset").get<std::string>());
    o.edit_mode = ParsePairEditMode(j.at("edit_mode").get<std::string>());
    o.clip_frames = j.at("clip_frames").get<int>();
    o.clip_stride = j.at("clip_stride").get<int>();
    if (j.contains("frames"))
      o.frames = ParseClipFrameSource(j["frames"].get<std::string>());
    o.refine_poses = j.value("refine_poses", false);
    if (j.contains("remove_instances"))
      o.remove_instances =
          j["remove_instances"].get<std::vector<std::string>>();
    o.width = j.at("width").get<int>();
    o.height = j.at("height").get<int>();
    o.resize_mode = ParseResizeMode(j.at("resize_mode").get<std::string>());
    o.fps = j.at("fps").get<double>();
    o.video_preset = j.value("video_preset", o.video_preset);
    o.video_crf = j.value("video_crf", o.video_crf);
    o.min_confidence = j.at("min_confidence").get<double>();
    o.min_depth_m = j.at("min_depth_m").get<double>();
    o.max_depth_m = j.at("max_depth_m").get<double>();
    o.splat_radius_px = j.at("splat_radius_px").get<double>();
    o.lidar_window_before_s = j.at("lidar_window_s").at(0).get<double>();
    o.lidar_window_after_s = j.at("lidar_window_s").at(1).get<double>();
    if (j.contains("lidar_dense_window")) {
      o.lidar_dense_window =
          ParseLidarWindow(j["lidar_dense_window"].get<std::string>());
      o.lidar_dense_width = j.at("lidar_dense_width").get<int>();
    }
    if (j.contains("lidar_dense_objects")) {
      o.lidar_dense_objects =
          ParseLidarObjects(j["lidar_dense_objects"].get<std::string>());
    }
  } catch (const json::exception& e) {
    ThrowInputError(what, "options: ", e.what());
  }
  return o;
}

// One dataset (and scene folders) per distinct set of inputs and clip
// options, opened on first use.
struct OpenInputs {
  std::unique_ptr<DriveDataset> dataset;
  std::map<std::string, int> clip_index;
  std::unique_ptr<SceneFolders> folders;
};

OpenInputs& InputsFor(const BuildDatasetOptions& opt,
                      std::map<std::string, OpenInputs>* cache) {
  const json key = {opt.InputsJson(), opt.version, opt.clip_frames,
                    opt.clip_stride, ToString(opt.frames)};
  OpenInputs& in = (*cache)[key.dump()];
  if (in.dataset) return in;
  in.dataset = OpenDriveDataset(internal::DatasetOptionsOf(opt));
  const std::vector<std::string> ids = in.dataset->ClipIds();
  for (size_t i = 0; i < ids.size(); ++i)
    in.clip_index[ids[i]] = static_cast<int>(i);
  const SceneSourceTraits traits =
      CreateSceneSource(opt.SceneSourceName())->Traits();
  if (traits.needs_path) {
    in.folders = std::make_unique<SceneFolders>(
        opt.monst3r_root, opt.monst3r_map, traits.folder_marker);
  }
  return in;
}

// Writes the exports of one pair into its folder (through a temporary
// folder beside the files, moved into place) and rewrites its meta.json.
void ExportPair(const std::string& out,
                const std::string& pair_dir,
                const std::vector<ExportFormat>& formats,
                const std::vector<std::unique_ptr<Exporter>>& exporters,
                std::map<std::string, OpenInputs>* cache) {
  PairMeta meta = ReadPairMeta(pair_dir);
  BuildDatasetOptions opt = OptionsOfPair(meta, pair_dir);
  opt.out = out;
  opt.exports = formats;
  opt.Check();
  OpenInputs& in = InputsFor(opt, cache);
  internal::ClipContext ctx;
  ctx.dataset = in.dataset.get();
  ctx.clip_index = &in.clip_index;
  ctx.options = &opt;
  ctx.folders = in.folders.get();
  ctx.exporters = &exporters;
  const DriveClip clip = in.dataset->LoadClip(meta.clip_id);
  internal::CheckClipForExports(ctx, clip);
  const int full_size_images =
      CreateSceneSource(opt.SceneSourceName())->Traits().full_size_images;
  const internal::ClipFrames frames =
      internal::ReadClipFrames(clip, opt, full_size_images);
  const std::string path =
      in.folders ? in.folders->Find(meta.clip_id).value_or("") : "";
  const ConditionScene scene =
      internal::BuildClipScene(clip, frames.full, path, opt);
  const BoxSequences boxes =
      internal::ClipVehicleBoxes(clip, scene.metric(), opt);
  const internal::RenderKeep keep = internal::ExportRenderKeep(ctx, opt);
  internal::ConditionRender cond;
  if (keep.native_frames || keep.depth)
    cond = internal::RenderCondition(scene, boxes, frames.gt, opt, keep);
  const auto exports =
      internal::PrepareClipExports(ctx, clip, scene, frames, cond, boxes);
  const std::string tmp = pair_dir + "/.export-tmp";
  fs::remove_all(tmp);
  fs::create_directories(tmp);
  for (const auto& x : exports) {
    // The pair's gt.mp4 is the video of its frames when the export takes
    // them (same decode, preset and CRF).
    const std::string gt = pair_dir + "/gt.mp4";
    if (x->clip.images == &frames.gt && fs::is_regular_file(gt))
      x->clip.images_video = gt;
    x->exporter->WriteClip(x->clip, tmp, &meta);
  }
  for (const auto& e : fs::directory_iterator(tmp)) {
    const fs::path target = fs::path(pair_dir) / e.path().filename();
    fs::remove_all(target);
    fs::rename(e.path(), target);
  }
  fs::remove_all(tmp);
  // The exporters' entries into the pair's own meta.json text (a round trip
  // through PairMeta would move the poses by an ulp).
  const std::string meta_path = pair_dir + "/meta.json";
  json j = json::parse(ReadFileText(meta_path));
  const json updated = json::parse(PairMetaToJson(meta));
  j["files"] = updated.at("files");
  if (updated.contains("upstream_scene_idx"))
    j["upstream_scene_idx"] = updated["upstream_scene_idx"];
  WriteFileAtomic(meta_path, j.dump(2) + "\n");
}

}  // namespace

int ExportPairs(const std::string& out,
                const std::vector<ExportFormat>& formats,
                const ExportOptions& options,
                bool quiet) {
  GEODRIVE_CHECK_INPUT(!formats.empty(), "export: --format is required");
  GEODRIVE_CHECK_INPUT(fs::is_regular_file(out + "/manifest.jsonl"), out,
                       ": not a build-dataset output (no manifest.jsonl)");
  const OutputFolderLock lock(out + "/.lock", out + ": output folder",
                              OutputFolderLock::Mode::kExclusive);
  std::vector<std::unique_ptr<Exporter>> exporters;
  for (const ExportFormat format : formats)
    exporters.push_back(CreateExporter(format, options));
  std::map<std::string, OpenInputs> cache;
  int pairs = 0;
  for (const ManifestEntry& e : ReadManifest(out + "/manifest.jsonl")) {
    const std::string dir = out + "/" + e.pair_dir;
    ExportPair(out, dir, formats, exporters, &cache);
    ++pairs;
    if (!quiet) std::cerr << "export: " << e.clip_id << "\n";
  }
  for (const auto& x : exporters) x->Finish(out);
  return pairs;
}

}  // namespace geodrive
