#include "dataset/build_dataset.h"

#include <glog/logging.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include "dataset/drive_dataset.h"
#include "dataset/internal/pair_builder.h"
#include "dataset/pairs.h"
#include "dataset/scene_folders.h"
#include "dataset/scene_source.h"
#include "geometry/util/files.h"
#include "geometry/util/hash.h"
#include "geometry/util/json_depth.h"
#include "geometry/util/names.h"
#include "geometry/util/output_file.h"
#include "geometry/util/progress.h"
#include "geometry/util/status.h"
#include "render/dynamic_edit.h"
#include "render/presets.h"

namespace geodrive {

namespace fs = std::filesystem;
using nlohmann::json;

std::string ToString(PairEditMode mode) {
  switch (mode) {
    case PairEditMode::k3d:
      return "3d";
    case PairEditMode::k2d:
      return "2d";
    case PairEditMode::kNone:
      return "none";
  }
  return "none";
}

PairEditMode ParsePairEditMode(const std::string& text) {
  if (text == "3d") return PairEditMode::k3d;
  if (text == "2d") return PairEditMode::k2d;
  if (text == "none") return PairEditMode::kNone;
  ThrowInputError("edit mode", "'", text, "' is not one of 3d, 2d, none");
}

std::string ShiftedPairId(const std::string& clip_id, double offset_m) {
  // The magnitude to the millimetre: "%.3f" with trailing zeros dropped.
  char text[64];
  std::snprintf(text, sizeof text, "%.3f", std::abs(offset_m));
  std::string m = text;
  while (!m.empty() && m.back() == '0') m.pop_back();
  if (!m.empty() && m.back() == '.') m.pop_back();
  std::replace(m.begin(), m.end(), '.', 'p');
  if (m == "0") return clip_id + "_shift_0m";
  return clip_id + (offset_m > 0 ? "_shift_left_" : "_shift_right_") + m + "m";
}

std::vector<Rigid3d> ShiftTrajectoryLaterally(
    const std::vector<Rigid3d>& scene_from_cam,
    const Rigid3d& ego_from_cam,
    double offset_m) {
  const Rigid3d shift(Eigen::Quaterniond::Identity(),
                      Eigen::Vector3d(0, offset_m, 0));
  const Rigid3d moved_cam = ego_from_cam.Inverse() * shift * ego_from_cam;
  std::vector<Rigid3d> out;
  out.reserve(scene_from_cam.size());
  for (const Rigid3d& pose : scene_from_cam) out.push_back(pose * moved_cam);
  return out;
}

namespace {

// The novel-view options (BuildDatasetOptions::lateral_offsets_m).
void CheckLateralOffsets(const BuildDatasetOptions& opt) {
  if (opt.lateral_offsets_m.empty()) return;
  std::set<std::string> ids;
  for (const double d : opt.lateral_offsets_m) {
    GEODRIVE_CHECK_INPUT(std::isfinite(d) && std::abs(d) <= 100,
                         "build-dataset: lateral offset ", d,
                         " m is not a number within [-100, 100] m");
    GEODRIVE_CHECK_INPUT(ids.insert(ShiftedPairId("", d)).second,
                         "build-dataset: lateral offset ", d,
                         " m is listed twice (offsets are kept to the mm)");
  }
  GEODRIVE_CHECK_INPUT(opt.cameras.empty(),
                       "build-dataset: lateral offsets (novel views) are "
                       "single-camera; drop --cameras");
  GEODRIVE_CHECK_INPUT(opt.edit_mode != PairEditMode::k2d,
                       "build-dataset: lateral offsets need --edit-mode 3d "
                       "or none (the 2D crop-and-paste follows the recorded "
                       "view's boxes)");
  GEODRIVE_CHECK_INPUT(opt.exports.empty(),
                       "build-dataset: lateral offsets (novel views) write "
                       "GeoDrive pairs only; drop --export");
}

}  // namespace

std::string BuildDatasetOptions::SceneSourceName() const {
  if (geometry != "auto") return geometry;
  return monst3r_root.empty() ? "lidar" : "monst3r";
}

void BuildDatasetOptions::Check() const {
  GEODRIVE_CHECK_INPUT(!dataroot.empty(),
                       "build-dataset: --dataroot is required");
  GEODRIVE_CHECK_INPUT(fs::is_directory(dataroot), dataroot,
                       ": dataroot is not a directory");
  GEODRIVE_CHECK_INPUT(!out.empty(), "build-dataset: --out is required");
  const std::string source = SceneSourceName();
  if (CreateSceneSource(source)->Traits().needs_path) {
    GEODRIVE_CHECK_INPUT(!monst3r_root.empty(), "build-dataset: --geometry ",
                         source, " needs --monst3r ROOT (ROOT/<clip id>/)");
    GEODRIVE_CHECK_INPUT(fs::is_directory(monst3r_root), monst3r_root,
                         ": MonST3R root is not a directory");
  }
  GEODRIVE_CHECK_INPUT(threads >= 1 && threads <= 256,
                       "build-dataset: --threads must be 1..256");
  GEODRIVE_CHECK_INPUT(
      shard_count >= 1 && shard_index >= 0 && shard_index < shard_count,
      "build-dataset: --shard must be i/N with 0 <= i < N");
  GEODRIVE_CHECK_INPUT(
      width >= 16 && height >= 16 && width <= 16384 && height <= 16384,
      "build-dataset: output size must be within 16..16384");
  GEODRIVE_CHECK_INPUT(fps > 0 && fps <= 240,
                       "build-dataset: --fps must be in (0, 240]");
  GEODRIVE_CHECK_INPUT(clip_frames >= 1 && clip_stride >= 1,
                       "build-dataset: --clip-frames and --stride must be at "
                       "least 1");
  GEODRIVE_CHECK_INPUT(min_confidence >= 0 && min_confidence <= 1,
                       "build-dataset: --min-confidence must be in [0, 1]");
  GEODRIVE_CHECK_INPUT(
      min_depth_m >= 0 && max_depth_m > min_depth_m,
      "build-dataset: depth range must satisfy 0 <= min < max");
  GEODRIVE_CHECK_INPUT(splat_radius_px >= 0 && splat_radius_px <= 16,
                       "build-dataset: --splat-radius must be in [0, 16]");
  // Encoder options fail the run at start, not every clip.
  GEODRIVE_CHECK_INPUT(video_crf >= 0 && video_crf <= 51,
                       "build-dataset: --crf must be in 0..51 (x264), got ",
                       video_crf);
  static const char* const kX264Presets[] = {
      "ultrafast", "superfast", "veryfast", "faster",   "fast",
      "medium",    "slow",      "slower",   "veryslow", "placebo"};
  GEODRIVE_CHECK_INPUT(
      std::find(std::begin(kX264Presets), std::end(kX264Presets),
                video_preset) != std::end(kX264Presets),
      "build-dataset: --x264-preset '", video_preset,
      "' is not an x264 preset (ultrafast superfast veryfast faster fast "
      "medium slow slower veryslow placebo)");
  GEODRIVE_CHECK_INPUT(
      remove_instances.empty() || edit_mode != PairEditMode::kNone,
      "build-dataset: --remove-instance needs --edit-mode 3d "
      "or 2d, not none");
  if (!cameras.empty()) {  // surround view (dataset/rig.h)
    GEODRIVE_CHECK_INPUT(source == "lidar" || source == "lidar-dense",
                         "build-dataset: --cameras needs metric geometry "
                         "shared by the rig (--geometry lidar or lidar-dense), "
                         "not ",
                         source);
    GEODRIVE_CHECK_INPUT(!lossless_frames,
                         "build-dataset: --lossless-frames writes one "
                         "camera's frame folders; with --cameras the pairs "
                         "hold gt_<CAM>.mp4 / cond_<CAM>.mp4 only (--crf 0 "
                         "for the least loss)");
    for (const ExportFormat format : exports) {
      GEODRIVE_CHECK_INPUT(
          CreateExporter(format, export_options)->WritesRigs(),
          "build-dataset: --export ", ToString(format),
          " is single-camera (its trainer reads one camera's clips); drop "
          "--cameras or that format (drivestudio and rds-hq take a rig)");
    }
  }
  CheckLateralOffsets(*this);
  GEODRIVE_CHECK_INPUT(export_options.Check(),
                       "build-dataset: --val-fraction must be in [0, 1], got ",
                       export_options.val_fraction);
  for (const ExportFormat format : exports) {
    const ExportRequirements req =
        CreateExporter(format, export_options)->Requirements();
    GEODRIVE_CHECK_INPUT(AcceptsFrameCount(req, clip_frames),
                         "build-dataset: --export ", ToString(format),
                         " needs ", FrameCountText(req),
                         " per clip; --clip-frames is ", clip_frames);
    // A guidance is the points on black: the released preset puts the real
    // image in frame 0.
    GEODRIVE_CHECK_INPUT(
        !req.depth || preset != RenderPreset::kGeodriveCompat,
        "build-dataset: --export ", ToString(format),
        " needs a z-buffer preset (paper or footprint), not geodrive-compat");
  }
}

std::string BuildDatasetOptions::ContentOptionsJson() const {
  json j;  // nlohmann::json objects keep keys sorted: stable text
  j["version"] = version;
  // Only non-default formats: nuScenes outputs keep their identity.
  if (dataset != DatasetFormat::kNuscenes) j["dataset"] = ToString(dataset);
  j["geometry"] = SceneSourceName();
  j["preset"] = ToString(preset);
  j["edit_mode"] = ToString(edit_mode);
  j["clip_frames"] = clip_frames;
  j["clip_stride"] = clip_stride;
  // Written only when not the default, so that the hash of existing builds
  // (all frames) stays valid for resuming them.
  if (frames != ClipFrameSource::kAll) j["frames"] = ToString(frames);
  if (refine_poses) j["refine_poses"] = true;
  if (!cameras.empty()) j["cameras"] = cameras;
  if (!remove_instances.empty()) j["remove_instances"] = remove_instances;
  // Novel-view pairs: each pair's own offset is in its id and meta.json, so
  // that a run with more offsets keeps the pairs already built.
  if (!lateral_offsets_m.empty()) j["novel_views"] = true;
  // One name as before ("geodrive-upstream"), so that earlier pairs keep
  // their hash.
  if (!exports.empty()) j["export"] = ToString(exports);
  j["width"] = width;
  j["height"] = height;
  j["resize_mode"] = ToString(resize_mode);
  j["fps"] = fps;
  j["lossless_frames"] = lossless_frames;
  j["video_preset"] = video_preset;
  j["video_crf"] = video_crf;
  j["min_confidence"] = min_confidence;
  j["min_depth_m"] = min_depth_m;
  j["max_depth_m"] = max_depth_m;
  j["splat_radius_px"] = splat_radius_px;
  j["lidar_window_s"] = {lidar_window_before_s, lidar_window_after_s};
  // Only for lidar-dense, so that the other sources' option hashes (and
  // their pairs on resume) stay as they were.
  if (SceneSourceName() == "lidar-dense") {
    j["lidar_dense_window"] = ToString(lidar_dense_window);
    j["lidar_dense_width"] = lidar_dense_width;
    // Only when not the default, so that earlier pairs keep their hash.
    if (lidar_dense_objects != LidarObjects::kRemove)
      j["lidar_dense_objects"] = ToString(lidar_dense_objects);
  }
  return j.dump();
}

std::string BuildDatasetOptions::InputsJson() const {
  const auto absolute = [](const std::string& path) {
    std::error_code ec;
    const fs::path p = fs::weakly_canonical(fs::absolute(path), ec);
    return ec ? fs::absolute(path).lexically_normal().string() : p.string();
  };
  json j;  // sorted keys: stable text
  j["dataroot"] = absolute(dataroot);
  if (!monst3r_root.empty() &&
      CreateSceneSource(SceneSourceName())->Traits().needs_path) {
    j["root"] = absolute(monst3r_root);
    if (!monst3r_map.empty()) j["root_map"] = absolute(monst3r_map);
  }
  return j.dump();
}

void BuildQualityTotals::Add(const PairQuality& q) {
  ++pairs;
  if (!q.coverage.empty()) coverage0_sum += q.coverage.front();
  if (!q.psnr_static.empty() && q.psnr_static.front()) {
    ++psnr0_pairs;
    psnr0_sum += *q.psnr_static.front();
  }
  if (q.supported_fraction && q.coverage_of_supported) {
    ++completion_pairs;
    supported_sum += *q.supported_fraction;
    coverage_of_supported_sum += *q.coverage_of_supported;
  }
  if (q.completion_holdout) {
    ++holdout_pairs;
    mae_sum += q.completion_holdout->mae_m;
    rmse_sum += q.completion_holdout->rmse_m;
    within_5_sum += q.completion_holdout->within_5_percent;
    within_10_sum += q.completion_holdout->within_10_percent;
  }
}

std::string BuildQualityTotals::BriefReport() const {
  if (pairs == 0) return "";
  std::ostringstream os;
  os << std::fixed << std::setprecision(3) << "frame 0 of " << pairs
     << " pairs built (means): coverage " << coverage0_sum / pairs;
  if (psnr0_pairs)
    os << std::setprecision(1) << ", static-region PSNR "
       << psnr0_sum / psnr0_pairs << " dB";
  if (completion_pairs) {
    os << std::setprecision(3) << "; LiDAR supports "
       << supported_sum / completion_pairs << " of the image, "
       << coverage_of_supported_sum / completion_pairs << " of it completed";
  }
  if (holdout_pairs) {
    const double n = holdout_pairs;
    os << std::setprecision(2) << "; held-out returns: MAE " << mae_sum / n
       << " m, RMSE " << rmse_sum / n << " m, within 5 % "
       << std::setprecision(3) << within_5_sum / n << ", within 10 % "
       << within_10_sum / n;
  }
  return os.str();
}

std::string BuildDatasetSummary::BriefReport() const {
  std::ostringstream os;
  os << "pairs built " << built << ", skipped (already built) "
     << skipped_existing;
  if (skipped_no_monst3r)
    os << ", skipped (no MonST3R folder) " << skipped_no_monst3r;
  if (rebuilt_broken) os << ", rebuilt (broken) " << rebuilt_broken;
  if (rebuilt_mismatched)
    os << ", rebuilt (other options) " << rebuilt_mismatched;
  if (kept_mismatched) os << ", kept (other options) " << kept_mismatched;
  if (rebuilt_other_inputs)
    os << ", rebuilt (other inputs) " << rebuilt_other_inputs;
  if (log_write_errors) os << ", log write errors " << log_write_errors;
  os << ", failed " << failed;
  for (const auto& [stage, n] : failures_by_stage)
    os << " [" << stage << ": " << n << "]";
  os << " of " << clips_total << " clips in " << seconds_total << " s";
  if (interrupted) os << " (interrupted: rerun to resume)";
  if (quality.pairs) os << "\n" << quality.BriefReport();
  // Wall seconds, then the worker threads' CPU seconds (keys with
  // internal::kCpuStagePrefix; the scale fit's CPU is inside geometry's).
  const std::string cpu = internal::kCpuStagePrefix;
  os << "\ntime per stage (s, summed over clips):";
  for (const auto& [stage, s] : seconds_by_stage) {
    if (stage.rfind(cpu, 0) != 0) os << " " << stage << " " << s;
  }
  bool first = true;
  for (const auto& [stage, s] : seconds_by_stage) {
    if (stage.rfind(cpu, 0) != 0) continue;
    if (first) os << "\nCPU per stage (s, summed over clips, worker threads):";
    first = false;
    os << " " << stage.substr(cpu.size()) << " " << s;
  }
  return os.str();
}

namespace {

using internal::BuildPair;
using internal::ClipContext;
using internal::StageError;

// Appends a line; returns the error instead of throwing (a log that cannot be
// written fails the run, it does not abort it).
std::string AppendLine(JsonlAppender* log, const std::string& line) {
  try {
    log->Append(line);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

enum class PairState {
  kMissing,
  kComplete,
  kOtherOptions,
  kOtherInputs,
  kBroken
};

// The inputs recorded in a pair's options (BuildDatasetOptions::InputsJson),
// "" for pairs built before they were recorded.
std::string RecordedInputs(const PairMeta& meta) {
  try {
    const json options = json::parse(meta.options_json);
    const auto it = options.find("inputs");
    if (it != options.end()) return it->dump();
  } catch (const std::exception&) {
  }
  return "";
}

// A pair folder counts as finished when its meta.json reads, it was built
// from this run's inputs (pairs that recorded none pass), its options hash is
// this run's, and every file it lists is there with its recorded size.
// `meta_out` (optional) receives the metadata when it reads.
PairState VerifyPair(const std::string& dir,
                     const std::string& options_hash,
                     const std::string& inputs,
                     std::string* why,
                     PairMeta* meta_out = nullptr) {
  std::error_code ec;
  if (!fs::exists(dir, ec)) return PairState::kMissing;
  PairMeta meta;
  try {
    meta = ReadPairMeta(dir);
  } catch (const std::exception& e) {
    *why = e.what();
    return PairState::kBroken;
  }
  if (meta_out) *meta_out = meta;
  const std::string recorded = RecordedInputs(meta);
  if (!recorded.empty() && recorded != inputs) {
    *why = "built from " + recorded;
    return PairState::kOtherInputs;
  }
  if (meta.options_hash != options_hash) {
    *why = "options_hash " + meta.options_hash;
    return PairState::kOtherOptions;
  }
  for (const auto& [role, name] : meta.files) {
    const std::string path = dir + "/" + name;
    if (!fs::exists(path, ec)) {
      *why = path + " (" + role + ") is missing";
      return PairState::kBroken;
    }
    const auto size = meta.file_sizes.find(name);
    if (size != meta.file_sizes.end() && fs::is_regular_file(path, ec) &&
        fs::file_size(path, ec) != size->second) {
      *why = path + " is " + std::to_string(fs::file_size(path, ec)) +
             " bytes, meta.json says " + std::to_string(size->second);
      return PairState::kBroken;
    }
  }
  return PairState::kComplete;
}

// Puts a freshly built pair in place, replacing an existing (stale or broken)
// one: the old folder is moved aside first, so a crash leaves either the old
// or the new pair (RecoverClipFolders restores the old one).
void ReplaceDirectory(const std::string& tmp, const std::string& final_dir) {
  std::error_code ec;
  const fs::path final_path(final_dir);
  const std::string aside = (final_path.parent_path() /
                             (".replaced-" + final_path.filename().string()))
                                .string();
  const bool replacing = fs::exists(final_dir, ec);
  if (replacing) {
    fs::remove_all(aside, ec);
    fs::rename(final_dir, aside, ec);
    GEODRIVE_CHECK_INPUT(!ec, final_dir, ": cannot move the old pair aside (",
                         ec.message(), ")");
  }
  CommitDirectory(tmp, final_dir);
  if (replacing) fs::remove_all(aside, ec);
}

// Cleans what a killed run left of clip `id`: its temporary folder, and a pair
// moved aside for replacement (restored when the new one never landed).
void RecoverClipFolders(const std::string& out, const std::string& id) {
  std::error_code ec;
  fs::remove_all(out + "/pairs/.tmp-" + id, ec);
  const std::string aside = out + "/pairs/.replaced-" + id;
  if (!fs::exists(aside, ec)) return;
  if (fs::exists(out + "/pairs/" + id, ec)) {
    fs::remove_all(aside, ec);
  } else {
    fs::rename(aside, out + "/pairs/" + id, ec);
  }
}

std::string ShardSuffix(int index, int count) {
  return count == 1 ? ""
                    : ".shard-" + std::to_string(index) + "-of-" +
                          std::to_string(count);
}

double Mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0.0 : s / v.size();
}

// A surround-view pair's mean coverage is over every camera's frames.
ManifestEntry EntryFromMeta(const PairMeta& meta) {
  std::vector<double> coverage = meta.quality.coverage;
  std::vector<std::string> cameras;
  if (!meta.views.empty()) coverage.clear();
  for (const PairView& v : meta.views) {
    coverage.insert(coverage.end(), v.coverage.begin(), v.coverage.end());
    cameras.push_back(v.channel);
  }
  return {meta.clip_id,
          "pairs/" + meta.clip_id,
          meta.scene_name,
          static_cast<int>(meta.frames.size()),
          meta.geometry_source,
          meta.pose_units,
          std::min(1.0, std::max(0.0, Mean(coverage))),
          meta.options_hash,
          cameras};
}

// What the manifest of a run lists: the pairs of the dataset's clips (all of
// them, whatever --clips, --max-clips or the shard), of the run's options
// (and, with keep_mismatched, of other options) and inputs. Written to
// OUT/.run.json by every run (the shards of one build write the same text),
// read by --merge.
struct RunRecord {
  std::set<std::string> clips;
  std::string options_hash;
  std::string inputs;  // BuildDatasetOptions::InputsJson
  bool keep_mismatched = false;
};

std::string RunRecordPath(const std::string& out) { return out + "/.run.json"; }

std::string RunRecordJson(const RunRecord& run) {
  json j;
  j["clips"] = run.clips;  // a sorted array
  j["options_hash"] = run.options_hash;
  j["inputs"] = json::parse(run.inputs);
  j["keep_mismatched"] = run.keep_mismatched;
  return j.dump(1) + "\n";
}

// The record of the last run in `out`; nullopt when there is none (outputs
// of earlier versions: the manifest then lists every pair folder).
std::optional<RunRecord> ReadRunRecord(const std::string& out) {
  const std::string path = RunRecordPath(out);
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  RunRecord run;
  try {
    const json j = internal::ParseJson(ReadFileText(path, 1ull << 30), path);
    for (const auto& c : j.at("clips")) run.clips.insert(c.get<std::string>());
    run.options_hash = j.at("options_hash").get<std::string>();
    run.inputs = j.at("inputs").dump();
    run.keep_mismatched = j.at("keep_mismatched").get<bool>();
  } catch (const json::exception& e) {
    ThrowInputError(path, "not a build-dataset run record (", e.what(), ")");
  }
  return run;
}

// Rebuilds manifest.jsonl (from pair folders) and failures.jsonl (last failure
// per clip without a pair, from all failure logs) sorted by clip id. With a
// run record, only the pairs it describes are listed (the others stay on disk
// and are reported) and only its clips' failures. Returns the number of pairs.
int RewriteLogs(const std::string& out, const RunRecord* run) {
  std::vector<std::string> ids;
  if (fs::is_directory(out + "/pairs")) {
    for (const auto& e : fs::directory_iterator(out + "/pairs")) {
      const std::string name = e.path().filename().string();
      if (e.is_directory() && name.rfind(".", 0) != 0 &&
          fs::exists(e.path() / "meta.json")) {
        ids.push_back(name);
      }
    }
  }
  std::sort(ids.begin(), ids.end());
  std::string manifest;
  std::vector<std::string> listed;
  int left_out = 0;
  std::string first_left_out;
  for (const auto& id : ids) {
    const std::string dir = out + "/pairs/" + id;
    if (run == nullptr) {
      manifest += ManifestEntryToJson(EntryFromMeta(ReadPairMeta(dir))) + "\n";
      listed.push_back(id);
      continue;
    }
    std::string why;
    PairMeta meta;
    PairState state = PairState::kMissing;
    if (!run->clips.count(id)) {
      why = "not a clip of this run's dataroot and clip options";
    } else {
      state = VerifyPair(dir, run->options_hash, run->inputs, &why, &meta);
    }
    if (state == PairState::kComplete ||
        (state == PairState::kOtherOptions && run->keep_mismatched)) {
      manifest += ManifestEntryToJson(EntryFromMeta(meta)) + "\n";
      listed.push_back(id);
    } else {
      if (left_out++ == 0) first_left_out = id + ": " + why;
    }
  }
  if (left_out > 0) {
    std::cerr << "build-dataset: " << left_out << " pair folder(s) in " << out
              << "/pairs are not pairs of this run's clips, options and "
                 "inputs (first: "
              << first_left_out << "): left out of manifest.jsonl\n";
  }
  WriteFileAtomic(out + "/manifest.jsonl", manifest);
  std::map<std::string, FailureEntry> failures;
  std::vector<std::string> logs;
  for (const auto& e : fs::directory_iterator(out)) {
    const std::string name = e.path().filename().string();
    std::error_code ec;
    // Regular files only: a log that is a device or a pipe (a failures.jsonl
    // pointing at /dev/full) is not read back.
    if (name.rfind("failures", 0) == 0 && name.size() > 6 &&
        name.substr(name.size() - 6) == ".jsonl" &&
        fs::is_regular_file(e.path(), ec)) {
      logs.push_back(e.path().string());
    }
  }
  std::sort(logs.begin(), logs.end());
  for (const auto& log : logs) {
    for (const auto& f : ReadFailures(log)) failures[f.clip_id] = f;
  }
  const std::set<std::string> built(listed.begin(), listed.end());
  std::string text;
  for (const auto& [id, f] : failures) {
    if (!built.count(id) && (run == nullptr || run->clips.count(id)))
      text += FailureEntryToJson(f) + "\n";
  }
  WriteFileAtomic(out + "/failures.jsonl", text);
  return static_cast<int>(listed.size());
}

// The clips of `clips` that --clips names; an unknown id is an InputError.
std::vector<std::string> RequestedClips(std::vector<std::string> clips,
                                        const BuildDatasetOptions& opt) {
  const std::set<std::string> wanted(opt.clips.begin(), opt.clips.end());
  std::set<std::string> found;
  std::vector<std::string> kept;
  for (auto& c : clips) {
    if (wanted.count(c)) found.insert(c), kept.push_back(std::move(c));
  }
  for (const auto& id : wanted) {
    GEODRIVE_CHECK_INPUT(
        found.count(id), "build-dataset: clip '", id,
        "' is not a clip of this dataset (see `geodrive nuscenes-info`)");
  }
  return kept;
}

// This shard's share of `clips` (every shard_count-th), at most max_clips.
std::vector<std::string> ShardClips(const std::vector<std::string>& clips,
                                    const BuildDatasetOptions& opt) {
  std::vector<std::string> mine;
  for (size_t i = 0; i < clips.size(); ++i) {
    if (static_cast<int>(i % opt.shard_count) == opt.shard_index)
      mine.push_back(clips[i]);
  }
  if (opt.max_clips > 0 && static_cast<int>(mine.size()) > opt.max_clips)
    mine.resize(opt.max_clips);
  return mine;
}

// The clips of `mine` to build now. Stale temporary folders of a killed run
// are removed and half-replaced pairs restored (only this shard's own clips:
// other shards or MPI ranks may be writing theirs right now); finished pairs
// that verify are skipped, broken ones and those of other content options
// rebuilt (or kept with keep_mismatched), and the run says so.
std::vector<const std::string*> PendingClips(
    const std::vector<std::string>& mine,
    const BuildDatasetOptions& opt,
    BuildDatasetSummary* summary) {
  for (const auto& c : mine) RecoverClipFolders(opt.out, c);
  const std::string hash = StableHash64(opt.ContentOptionsJson());
  const std::string inputs = opt.InputsJson();
  std::vector<const std::string*> pending;
  std::string first_mismatch, first_other_inputs;
  for (const auto& c : mine) {
    std::string why;
    switch (VerifyPair(opt.out + "/pairs/" + c, hash, inputs, &why)) {
      case PairState::kMissing:
        pending.push_back(&c);
        break;
      case PairState::kComplete:
        ++summary->skipped_existing;
        break;
      case PairState::kOtherOptions:
        if (first_mismatch.empty()) first_mismatch = c + " (" + why + ")";
        if (opt.keep_mismatched) {
          ++summary->kept_mismatched;
        } else {
          ++summary->rebuilt_mismatched;
          pending.push_back(&c);
        }
        break;
      case PairState::kOtherInputs:
        if (first_other_inputs.empty())
          first_other_inputs = c + " (" + why + ")";
        ++summary->rebuilt_other_inputs;
        pending.push_back(&c);
        break;
      case PairState::kBroken:
        ++summary->rebuilt_broken;
        if (!opt.quiet)
          std::cerr << "build-dataset: " << c << ": " << why
                    << ": rebuilding it\n";
        pending.push_back(&c);
        break;
    }
  }
  if (summary->rebuilt_other_inputs > 0) {
    std::cerr << "build-dataset: " << summary->rebuilt_other_inputs
              << " pair(s) in " << opt.out
              << " were built from other inputs (first: " << first_other_inputs
              << "; this run " << inputs << "): rebuilding them\n";
  }
  const int mismatched = summary->kept_mismatched + summary->rebuilt_mismatched;
  if (mismatched > 0) {
    std::cerr << "build-dataset: " << mismatched << " pair(s) in " << opt.out
              << " were built with other content options (first: "
              << first_mismatch << "; this run " << hash << "): "
              << (opt.keep_mismatched ? "kept (--keep-mismatched)"
                                      : "rebuilding them")
              << "\n";
  }
  return pending;
}

// Shards that run together must deal the clips the same way: a running shard
// of another count would build some of this shard's clips at the same time.
void CheckNoShardOfAnotherCount(const BuildDatasetOptions& opt) {
  const std::string own = "-of-" + std::to_string(opt.shard_count);
  for (const auto& e : fs::directory_iterator(opt.out)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(".lock.shard-", 0) != 0 || EndsWith(name, own)) continue;
    GEODRIVE_CHECK_INPUT(!LockFileIsHeld(e.path().string()), opt.out,
                         ": output folder: ", name.substr(6),
                         " is running (lock ", e.path().string(),
                         "); shards writing one folder together must all use "
                         "--shard i/",
                         opt.shard_count, " with the same count");
  }
}

// One lock per output folder, whatever the shard: OUT/.lock, exclusive for a
// run of all shards (and --merge), shared by the shards of one build, each of
// which also holds OUT/.lock.shard-<i>-of-<N> exclusively.
struct OutputLocks {
  explicit OutputLocks(const BuildDatasetOptions& opt)
      : folder(opt.out + "/.lock",
               opt.out + ": output folder",
               opt.shard_count == 1 ? OutputFolderLock::Mode::kExclusive
                                    : OutputFolderLock::Mode::kShared) {
    if (opt.shard_count == 1) return;
    shard = std::make_unique<OutputFolderLock>(
        opt.out + "/.lock" + ShardSuffix(opt.shard_index, opt.shard_count),
        opt.out + ": shard " + std::to_string(opt.shard_index) + "/" +
            std::to_string(opt.shard_count) + " of the output folder",
        OutputFolderLock::Mode::kExclusive);
    CheckNoShardOfAnotherCount(opt);
  }
  OutputFolderLock folder;
  std::unique_ptr<OutputFolderLock> shard;
};

}  // namespace

namespace {

// Clip ids are folder names: plain (adapters make them with MakeClipId,
// whose scene part goes through PathComponentFromName) and unique.
void CheckClipIdsAreFolderNames(const std::vector<std::string>& clips,
                                const std::string& dataroot) {
  std::set<std::string> seen;
  for (const auto& c : clips) {
    GEODRIVE_CHECK_INPUT(IsPlainPathComponent(c), dataroot, ": clip id '",
                         PathComponentFromName(c),
                         "' (percent-encoded) is not a plain folder name");
    GEODRIVE_CHECK_INPUT(seen.insert(c).second, dataroot, ": clip id '", c,
                         "' is listed twice");
  }
}

// The pair ids of `clips`: the clip ids themselves, or with lateral offsets
// every clip's novel-view pairs (clip order, then the offsets' order), each
// recorded in `novel` (optional) with its source clip and offset.
std::vector<std::string> PairIds(const std::vector<std::string>& clips,
                                 const BuildDatasetOptions& opt,
                                 std::map<std::string, PairNovelView>* novel) {
  if (opt.lateral_offsets_m.empty()) return clips;
  std::vector<std::string> ids;
  for (const std::string& clip : clips) {
    for (const double d : opt.lateral_offsets_m) {
      ids.push_back(ShiftedPairId(clip, d));
      if (novel) (*novel)[ids.back()] = PairNovelView{clip, d};
    }
  }
  return ids;
}

}  // namespace

namespace internal {

NovelViewScenes::NovelViewScenes(std::map<std::string, int> pairs_per_clip)
    : remaining_(std::move(pairs_per_clip)) {}

ConditionScene NovelViewScenes::Get(
    const std::string& clip_id, const std::function<ConditionScene()>& build) {
  std::unique_lock<std::mutex> lock(mutex_);
  std::promise<std::shared_ptr<const ConditionScene>> promise;
  Shared shared;
  const auto it = scenes_.find(clip_id);
  const bool first = it == scenes_.end();
  if (first) {
    shared = promise.get_future().share();
    scenes_[clip_id] = shared;
  } else {
    shared = it->second;
  }
  lock.unlock();
  if (first) {
    try {
      promise.set_value(std::make_shared<const ConditionScene>(build()));
    } catch (...) {
      promise.set_exception(std::current_exception());
    }
  }
  lock.lock();
  if (--remaining_[clip_id] <= 0) scenes_.erase(clip_id);
  lock.unlock();
  return *shared.get();  // a copy: each pair moves its own trajectory
}

const PairNovelView* NovelViewOf(const ClipContext& ctx,
                                 const std::string& pair_id) {
  if (ctx.novel_views == nullptr) return nullptr;
  const auto it = ctx.novel_views->find(pair_id);
  return it == ctx.novel_views->end() ? nullptr : &it->second;
}

void ShiftScene(const DriveClip& clip,
                const PairNovelView& view,
                ConditionScene* scene) {
  GEODRIVE_CHECK_INPUT(!clip.frames.empty(), clip.id, ": clip has no frames");
  GEODRIVE_CHECK_INPUT(
      scene->metric(), clip.id, ": a lateral offset of ", view.lateral_offset_m,
      " m needs metric geometry; the scene (", scene->description,
      ") is not in metres (use --geometry lidar, or MonST3R "
      "with LiDAR for its scale)");
  scene->trajectory.world_from_cam = ShiftTrajectoryLaterally(
      scene->trajectory.world_from_cam, clip.frames.front().ego_from_cam,
      view.lateral_offset_m);
}

void MarkNovelView(const std::string& pair_id,
                   const PairNovelView& view,
                   ConditionRender* cond,
                   PairMeta* meta) {
  meta->clip_id = pair_id;
  meta->novel_view = view;
  for (auto& psnr : cond->psnr_static) psnr.reset();
}

DriveDatasetOptions DatasetOptionsOf(const BuildDatasetOptions& opt) {
  DriveDatasetOptions dso;
  dso.format = opt.dataset;
  dso.root = opt.dataroot;
  dso.version = opt.version;
  dso.clip_frames = opt.clip_frames;
  dso.clip_stride = opt.clip_stride;
  dso.frames = opt.frames;
  dso.cameras = opt.cameras;
  if (!opt.cameras.empty() && opt.cameras.front() != "all")
    dso.channel = opt.cameras.front();
  return dso;
}

}  // namespace internal

namespace {

// The clips whose scene-source folder exists; a clip without one is counted
// as skipped, unless the user asked for it by id (then its build fails).
std::vector<std::string> ClipsWithFolders(std::vector<std::string> clips,
                                          const SceneFolders& folders,
                                          const BuildDatasetOptions& opt,
                                          BuildDatasetSummary* summary) {
  std::vector<std::string> kept;
  for (auto& c : clips) {
    if (folders.Find(c)) {
      kept.push_back(std::move(c));
    } else if (opt.clips.empty()) {
      ++summary->skipped_no_monst3r;
    } else {
      // Asked for explicitly: a missing folder is a failure.
      kept.push_back(std::move(c));
    }
  }
  return kept;
}

// After an unsharded run: the logs rewritten for the run's clips, the
// exporters' indexes and the report. A log or report that cannot be written
// (a full disk, a file-size limit, a device in its place) fails the run,
// naming the file.
void FinishRun(const BuildDatasetOptions& opt,
               const std::vector<std::unique_ptr<Exporter>>& exporters,
               RunRecord* run,
               BuildDatasetSummary* summary) {
  const auto write = [summary](const std::function<void()>& step) {
    try {
      step();
    } catch (const InputError& e) {
      ++summary->log_write_errors;
      std::cerr << "build-dataset: " << e.what() << "\n";
    } catch (const fs::filesystem_error& e) {
      ++summary->log_write_errors;
      std::cerr << "build-dataset: " << e.what() << "\n";
    }
  };
  write([&] { RewriteLogs(opt.out, run); });
  for (const auto& e : exporters) write([&] { e->Finish(opt.out); });
  write([&] { WriteBuildReport(opt.out, summary); });
}

}  // namespace

BuildDatasetSummary BuildDataset(BuildDatasetOptions opt) {
  opt.Check();
  const auto t_start = std::chrono::steady_clock::now();
  BuildDatasetSummary summary;
  // The dataset first (read only): a bad dataroot, table or camera list
  // leaves --out as it was.
  const std::unique_ptr<DriveDataset> dataset =
      OpenDriveDataset(internal::DatasetOptionsOf(opt));
  CreateOutputDirectory(opt.out + "/pairs");
  const OutputLocks locks(opt);
  if (!opt.quiet) std::cerr << "build-dataset: " << dataset->Describe() << "\n";
  std::vector<std::string> clips = dataset->ClipIds();
  CheckClipIdsAreFolderNames(clips, opt.dataroot);
  if (!opt.clips.empty()) clips = RequestedClips(std::move(clips), opt);
  std::map<std::string, int> clip_index;
  for (size_t i = 0; i < dataset->ClipIds().size(); ++i)
    clip_index[dataset->ClipIds()[i]] = static_cast<int>(i);
  ClipContext ctx;
  ctx.dataset = dataset.get();
  ctx.options = &opt;
  ctx.clip_index = &clip_index;
  std::vector<std::unique_ptr<Exporter>> exporters;
  for (const ExportFormat format : opt.exports)
    exporters.push_back(CreateExporter(format, opt.export_options));
  ctx.exporters = &exporters;
  std::unique_ptr<SceneFolders> folders;
  const SceneSourceTraits traits =
      CreateSceneSource(opt.SceneSourceName())->Traits();
  if (traits.needs_path) {
    folders = std::make_unique<SceneFolders>(opt.monst3r_root, opt.monst3r_map,
                                             traits.folder_marker);
    ctx.folders = folders.get();
    clips = ClipsWithFolders(std::move(clips), *folders, opt, &summary);
  }
  std::map<std::string, PairNovelView> novel_views;
  ctx.novel_views = &novel_views;
  const std::vector<std::string> mine =
      ShardClips(PairIds(clips, opt, &novel_views), opt);
  summary.clips_total = static_cast<int>(mine.size());

  const std::string suffix = ShardSuffix(opt.shard_index, opt.shard_count);
  RunRecord run;
  for (const std::string& id : PairIds(dataset->ClipIds(), opt, nullptr))
    run.clips.insert(id);
  run.options_hash = StableHash64(opt.ContentOptionsJson());
  run.inputs = opt.InputsJson();
  run.keep_mismatched = opt.keep_mismatched;
  WriteFileAtomic(RunRecordPath(opt.out), RunRecordJson(run));
  const std::vector<const std::string*> pending =
      PendingClips(mine, opt, &summary);
  std::map<std::string, int> pairs_per_clip;
  for (const std::string* id : pending) {
    const auto it = novel_views.find(*id);
    if (it != novel_views.end()) ++pairs_per_clip[it->second.source_clip_id];
  }
  internal::NovelViewScenes novel_scenes(std::move(pairs_per_clip));
  ctx.novel_scenes = &novel_scenes;
  JsonlAppender manifest(opt.out + "/manifest" + suffix + ".jsonl");
  JsonlAppender failures(opt.out + "/failures" + suffix + ".jsonl");
  ProgressReporter progress("build-dataset", pending.size(), 10.0, opt.quiet);
  std::mutex mutex;
  std::atomic<size_t> next{0};
  auto worker = [&] {
    std::map<std::string, double> local_seconds;
    while (!StopRequested()) {
      const size_t k = next.fetch_add(1);
      if (k >= pending.size()) break;
      const std::string& clip_id = *pending[k];
      const std::string tmp = opt.out + "/pairs/.tmp-" + clip_id;
      const std::string final_dir = opt.out + "/pairs/" + clip_id;
      RegisterTemporaryPath(tmp);  // removed if the run is killed by a signal
      std::string stage = "setup", error, error_log;
      PairQuality quality;
      try {
        // The last guard: nothing is written outside --out.
        CheckPathInside(final_dir, opt.out);
        fs::remove_all(tmp);
        fs::create_directories(tmp);
        const PairMeta meta = BuildPair(ctx, clip_id, tmp, &local_seconds);
        quality = meta.quality;
        stage = "commit";
        ReplaceDirectory(tmp, final_dir);
        error_log =
            AppendLine(&manifest, ManifestEntryToJson(EntryFromMeta(meta)));
      } catch (const StageError& e) {
        stage = e.stage;
        error = e.what();
      } catch (const std::exception& e) {
        error = e.what();
      }
      std::lock_guard<std::mutex> lock(mutex);
      if (error.empty()) {
        ++summary.built;
        summary.quality.Add(quality);
      } else {
        std::error_code ec;
        fs::remove_all(tmp, ec);
        ++summary.failed;
        ++summary.failures_by_stage[stage];
        error_log =
            AppendLine(&failures, FailureEntryToJson({clip_id, stage, error}));
        if (!opt.quiet)
          std::cerr << "build-dataset: " << clip_id << " failed at " << stage
                    << ": " << error << "\n";
      }
      if (!error_log.empty()) {  // a run failure, reported; never an abort
        ++summary.log_write_errors;
        std::cerr << "build-dataset: " << error_log << "\n";
      }
      progress.Advance(1, clip_id);
    }
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& [s, t] : local_seconds) summary.seconds_by_stage[s] += t;
  };
  std::vector<std::thread> pool;
  for (int t = 0;
       t < std::min<int>(opt.threads, std::max<size_t>(1, pending.size()));
       ++t) {
    pool.emplace_back(worker);
  }
  for (auto& th : pool) th.join();
  progress.Finish();
  summary.interrupted = StopRequested() && next.load() < pending.size();
  summary.seconds_total =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start)
          .count();
  if (opt.shard_count == 1) FinishRun(opt, exporters, &run, &summary);
  return summary;
}

int MergeBuildOutputs(const std::string& out,
                      const ExportOptions& export_options) {
  GEODRIVE_CHECK_INPUT(fs::is_directory(out + "/pairs"), out,
                       ": not a build-dataset output (no pairs/)");
  const OutputFolderLock lock(out + "/.lock", out + ": output folder",
                              OutputFolderLock::Mode::kExclusive);
  const std::optional<RunRecord> run = ReadRunRecord(out);
  const int n = RewriteLogs(out, run ? &*run : nullptr);
  // Every format's index (a no-op for a format no pair has).
  for (const ExportFormat format : AllExportFormats())
    CreateExporter(format, export_options)->Finish(out);
  WriteBuildReport(out, nullptr);
  return n;
}

}  // namespace geodrive
