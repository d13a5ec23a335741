#include "dataset/build_dataset.h"

#include <glog/logging.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <nlohmann/json.hpp>
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
  GEODRIVE_CHECK_INPUT(clip_frames >= 2 && clip_stride >= 1,
                       "build-dataset: bad clip options");
  GEODRIVE_CHECK_INPUT(min_confidence >= 0 && min_confidence <= 1,
                       "build-dataset: --min-confidence must be in [0, 1]");
  GEODRIVE_CHECK_INPUT(
      min_depth_m >= 0 && max_depth_m > min_depth_m,
      "build-dataset: depth range must satisfy 0 <= min < max");
  GEODRIVE_CHECK_INPUT(splat_radius_px >= 0 && splat_radius_px <= 16,
                       "build-dataset: --splat-radius must be in [0, 16]");
}

std::string BuildDatasetOptions::ContentOptionsJson() const {
  json j;  // nlohmann::json objects keep keys sorted: stable text
  j["version"] = version;
  j["geometry"] = SceneSourceName();
  j["preset"] = ToString(preset);
  j["edit_mode"] = ToString(edit_mode);
  j["clip_frames"] = clip_frames;
  j["clip_stride"] = clip_stride;
  // Written only when not the default, so that the hash of existing builds
  // (all frames) stays valid for resuming them.
  if (frames != ClipFrameSource::kAll) j["frames"] = ToString(frames);
  if (refine_poses) j["refine_poses"] = true;
  if (export_format == PairExport::kGeodriveUpstream)
    j["export"] = "geodrive-upstream";
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
  return j.dump();
}

std::string BuildDatasetSummary::BriefReport() const {
  std::ostringstream os;
  os << "pairs built " << built << ", skipped (already built) "
     << skipped_existing;
  if (skipped_no_monst3r)
    os << ", skipped (no MonST3R folder) " << skipped_no_monst3r;
  os << ", failed " << failed;
  for (const auto& [stage, n] : failures_by_stage)
    os << " [" << stage << ": " << n << "]";
  os << " of " << clips_total << " clips in " << seconds_total << " s";
  if (interrupted) os << " (interrupted: rerun to resume)";
  os << "\ntime per stage (s, summed over clips):";
  for (const auto& [stage, s] : seconds_by_stage)
    os << " " << stage << " " << s;
  return os.str();
}

namespace {

using internal::BuildPair;
using internal::ClipContext;
using internal::StageError;

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

ManifestEntry EntryFromMeta(const PairMeta& meta) {
  return {meta.clip_id,
          "pairs/" + meta.clip_id,
          meta.scene_name,
          static_cast<int>(meta.frames.size()),
          meta.geometry_source,
          meta.pose_units,
          std::min(1.0, std::max(0.0, Mean(meta.quality.coverage))),
          meta.options_hash};
}

// Rebuilds manifest.jsonl (from pair folders) and failures.jsonl (last failure
// per clip without a pair, from all failure logs) sorted by clip id. Returns
// the number of pairs.
int RewriteLogs(const std::string& out) {
  std::vector<std::string> ids;
  if (fs::is_directory(out + "/pairs")) {
    for (const auto& e : fs::directory_iterator(out + "/pairs")) {
      const std::string name = e.path().filename().string();
      if (e.is_directory() && name.rfind(".tmp-", 0) != 0 &&
          fs::exists(e.path() / "meta.json")) {
        ids.push_back(name);
      }
    }
  }
  std::sort(ids.begin(), ids.end());
  std::string manifest;
  for (const auto& id : ids) {
    manifest +=
        ManifestEntryToJson(EntryFromMeta(ReadPairMeta(out + "/pairs/" + id))) +
        "\n";
  }
  WriteFileAtomic(out + "/manifest.jsonl", manifest);
  std::map<std::string, FailureEntry> failures;
  std::vector<std::string> logs;
  for (const auto& e : fs::directory_iterator(out)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("failures", 0) == 0 && name.size() > 6 &&
        name.substr(name.size() - 6) == ".jsonl") {
      logs.push_back(e.path().string());
    }
  }
  std::sort(logs.begin(), logs.end());
  for (const auto& log : logs) {
    for (const auto& f : ReadFailures(log)) failures[f.clip_id] = f;
  }
  const std::set<std::string> built(ids.begin(), ids.end());
  std::string text;
  for (const auto& [id, f] : failures) {
    if (!built.count(id)) text += FailureEntryToJson(f) + "\n";
  }
  WriteFileAtomic(out + "/failures.jsonl", text);
  return static_cast<int>(ids.size());
}

}  // namespace

BuildDatasetSummary BuildDataset(BuildDatasetOptions opt) {
  opt.Check();
  const auto t_start = std::chrono::steady_clock::now();
  BuildDatasetSummary summary;
  fs::create_directories(opt.out + "/pairs");

  DriveDatasetOptions dso;
  dso.root = opt.dataroot;
  dso.version = opt.version;
  dso.clip_frames = opt.clip_frames;
  dso.clip_stride = opt.clip_stride;
  dso.frames = opt.frames;
  const std::unique_ptr<DriveDataset> dataset = OpenDriveDataset(dso);
  if (!opt.quiet) std::cerr << "build-dataset: " << dataset->Describe() << "\n";
  std::vector<std::string> clips = dataset->ClipIds();
  if (!opt.clips.empty()) {
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
    clips = std::move(kept);
  }
  std::map<std::string, int> clip_index;
  for (size_t i = 0; i < dataset->ClipIds().size(); ++i)
    clip_index[dataset->ClipIds()[i]] = static_cast<int>(i);
  ClipContext ctx;
  ctx.dataset = dataset.get();
  ctx.options = &opt;
  ctx.clip_index = &clip_index;
  std::unique_ptr<SceneFolders> folders;
  if (CreateSceneSource(opt.SceneSourceName())->Traits().needs_path) {
    folders = std::make_unique<SceneFolders>(
        opt.monst3r_root, opt.monst3r_map,
        opt.SceneSourceName() == "monst3r" ? "pred_traj.txt" : "");
    ctx.folders = folders.get();
    std::vector<std::string> kept;
    for (auto& c : clips) {
      if (folders->Find(c)) {
        kept.push_back(std::move(c));
      } else if (opt.clips.empty()) {
        ++summary.skipped_no_monst3r;
      } else {
        // Asked for explicitly: a missing folder is a failure.
        kept.push_back(std::move(c));
      }
    }
    clips = std::move(kept);
  }
  std::vector<std::string> mine;
  for (size_t i = 0; i < clips.size(); ++i) {
    if (static_cast<int>(i % opt.shard_count) == opt.shard_index)
      mine.push_back(clips[i]);
  }
  if (opt.max_clips > 0 && static_cast<int>(mine.size()) > opt.max_clips)
    mine.resize(opt.max_clips);
  summary.clips_total = static_cast<int>(mine.size());

  // Stale temporary folders of a killed run are removed (only this shard's own
  // clips: other shards or MPI ranks may be writing theirs right now); finished
  // pairs are skipped.
  for (const auto& c : mine) {
    std::error_code ec;
    fs::remove_all(opt.out + "/pairs/.tmp-" + c, ec);
  }
  std::vector<const std::string*> pending;
  for (const auto& c : mine) {
    if (fs::exists(opt.out + "/pairs/" + c + "/meta.json")) {
      ++summary.skipped_existing;
    } else {
      pending.push_back(&c);
    }
  }
  const std::string suffix = ShardSuffix(opt.shard_index, opt.shard_count);
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
      std::string stage = "setup", error;
      try {
        fs::remove_all(tmp);
        fs::create_directories(tmp);
        const PairMeta meta = BuildPair(ctx, clip_id, tmp, &local_seconds);
        stage = "commit";
        CommitDirectory(tmp, final_dir);
        manifest.Append(ManifestEntryToJson(EntryFromMeta(meta)));
      } catch (const StageError& e) {
        stage = e.stage;
        error = e.what();
      } catch (const std::exception& e) {
        error = e.what();
      }
      std::lock_guard<std::mutex> lock(mutex);
      if (error.empty()) {
        ++summary.built;
      } else {
        std::error_code ec;
        fs::remove_all(tmp, ec);
        ++summary.failed;
        ++summary.failures_by_stage[stage];
        failures.Append(FailureEntryToJson({clip_id, stage, error}));
        if (!opt.quiet)
          std::cerr << "build-dataset: " << clip_id << " failed at " << stage
                    << ": " << error << "\n";
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
  if (opt.shard_count == 1) {
    RewriteLogs(opt.out);
    if (opt.export_format == PairExport::kGeodriveUpstream)
      internal::WriteUpstreamIndex(opt.out);
    WriteBuildReport(opt.out, &summary);
  }
  return summary;
}

int MergeBuildOutputs(const std::string& out) {
  GEODRIVE_CHECK_INPUT(fs::is_directory(out + "/pairs"), out,
                       ": not a build-dataset output (no pairs/)");
  const int n = RewriteLogs(out);
  internal::WriteUpstreamIndex(out);  // no-op without exported pairs
  WriteBuildReport(out, nullptr);
  return n;
}

}  // namespace geodrive
