#pragma once
// `geodrive build-dataset`: nuScenes-like clips -> condition/video training
// pairs.
//
// Per clip (25 CAM_FRONT frames): GT frames at the output size, a frame-0 point
// cloud (MonST3R pointmap, metric through the LiDAR scale when LiDAR is
// present; or aggregated static LiDAR), rendered along the clip trajectory with
// dynamic editing from the clip's boxes, written as a pair folder
// (dataset/pairs.h). Jobs are resumable (pairs are committed atomically, a
// rerun skips finished pairs), thread-parallel over clips, and shardable
// (--shard i/N, MPI ranks).

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "dataset/drive_clip.h"
#include "dataset/drive_dataset.h"
#include "dataset/exporter.h"
#include "dataset/pairs.h"
#include "dataset/scene_source.h"
#include "geometry/camera.h"
#include "render/presets.h"

namespace geodrive {

// Object editing of a pair's condition from the clip's vehicle boxes.
enum class PairEditMode {
  k3d,    // segment and move the vehicles in 3D (render/dynamic_edit.h)
  k2d,    // the upstream 2D crop-and-paste
  kNone,  // render the static scene only
};
std::string ToString(PairEditMode mode);  // "3d", "2d", "none"
// Parses "3d", "2d" or "none"; throws InputError otherwise.
PairEditMode ParsePairEditMode(const std::string& text);

struct BuildDatasetOptions {
  // Dataset format of `dataroot`.
  DatasetFormat dataset = DatasetFormat::kNuscenes;
  // nuScenes root (holds <version>/, samples/, sweeps/), or a folder of
  // Waymo *.tfrecord segments.
  std::string dataroot;
  std::string version = "v1.0-mini";
  // ROOT/<clip_id>/ input folders of path-based scene sources (MonST3R
  // folders for geometry monst3r, depth folders for depth-folder, ...).
  std::string monst3r_root;
  // Optional mapping of folder names under monst3r_root to clip ids: the
  // clips.jsonl of `geodrive clips` (sample_%06d numbering) or "<folder>
  // <clip id>" lines (dataset/scene_folders.h).
  std::string monst3r_map;
  std::string out;  // output folder
  // Scene source name (dataset/scene_source.h: monst3r, lidar, depth-folder,
  // ...; a plug-in key, so a registered name rather than an enum); "auto" =
  // monst3r when monst3r_root is set, lidar otherwise (SceneSourceName()).
  std::string geometry = "auto";
  int threads = 1;  // clips in parallel
  int shard_index = 0, shard_count = 1;
  // Render preset: the paper's z-buffer or the released soft compositor.
  RenderPreset preset = RenderPreset::kPaper;
  // Object editing from the clip's boxes.
  PairEditMode edit_mode = PairEditMode::k3d;
  // Instances (the dataset's instance ids, e.g. nuScenes instance tokens)
  // removed from every condition that has them, in every camera of a rig:
  // their points and boxes are dropped (3d and 2d edit modes).
  std::vector<std::string> remove_instances;
  std::vector<std::string> clips;  // restrict to these clip ids (empty = all)
  int max_clips =
      0;  // 0 = no limit (after sharding filter: first N of the list)
  // Clip selection (dataset/drive_dataset.h): frames per clip, frames between
  // clip starts, and which frames (all, or keyframes only for extracts without
  // sweep files).
  int clip_frames = 25;
  int clip_stride = 6;
  ClipFrameSource frames = ClipFrameSource::kAll;
  // Surround view (dataset/rig.h): the cameras of every pair, the reference
  // (whose frames make the clips) first, or {"all"} (CAM_FRONT the
  // reference); empty = CAM_FRONT pairs. One scene per
  // clip rendered into every camera; per camera gt_<CAM>.mp4 and
  // cond_<CAM>.mp4, a rig-layout preview.png, meta.json views and seams.
  std::vector<std::string> cameras;
  // Novel views (`geodrive nvs-set`): for every clip and every offset here,
  // one pair whose condition is rendered along the clip's camera trajectory
  // shifted sideways, every frame's ego pose moved along its own y axis by
  // the offset (metres; ego frame x forward, y left, z up: positive = left),
  // the camera carried with it rigidly; its ground truth is the clip's real
  // frames. Pair ids are ShiftedPairId(clip, offset). Empty = one pair per
  // clip along the recorded trajectory. Needs metric geometry, a single
  // camera, edit mode 3d or none and no --export.
  std::vector<double> lateral_offsets_m;
  // Output video.
  int width = 720, height = 480;
  // Output framing: plain resize (GeoDrive training) or center crop
  // (inference).
  ResizeMode resize_mode = ResizeMode::kResize;
  double fps = 10.0;  // nuScenes 12 Hz clips are labelled 10 fps (as Vista)
  // Also write gt_frames/ and cond_frames/ PNG sequences.
  bool lossless_frames = false;
  // x264 preset and CRF of gt.mp4 / cond.mp4 (ultrafast keeps encoding at ~0.25
  // s per clip; slower presets give ~20 % smaller files at the same CRF).
  std::string video_preset = "ultrafast";
  int video_crf = 18;
  // Geometry filters (paper: tau 0.65, 0.1 - 100 m).
  double min_confidence = 0.65;
  double min_depth_m = 0.1, max_depth_m = 100.0;
  // Paper preset splat radius in output pixels (the 512x288 pointmap is sparser
  // than 720x480); the footprint preset sizes every point from its footprint.
  double splat_radius_px = 1.0;
  // LiDAR geometry source: sweeps within [t0 - before, t0 + after] (s) are
  // aggregated.
  double lidar_window_before_s = 0.5, lidar_window_after_s = 1.5;
  // lidar-dense geometry: which sweeps (causal: up to frame 0, the default;
  // clip: the whole clip; explicit: the window above) and the width of the
  // completed frame-0 depth (dataset/scene_source.h).
  LidarWindow lidar_dense_window = LidarWindow::kCausal;
  // lidar-dense: the returns inside annotated boxes (removed, or kept from
  // the frame-0 sweep).
  LidarObjects lidar_dense_objects = LidarObjects::kRemove;
  int lidar_dense_width = 800;
  // MonST3R geometry: refine the poses by reprojection over static pixels
  // (paper eq. 3) before rendering; meta.json reports the RMS before/after.
  bool refine_poses = false;
  // Keep pairs of OUT built with other content options (reported) instead of
  // rebuilding them.
  bool keep_mismatched = false;
  // Also write the pairs in other trainers' formats (dataset/exporter.h):
  // geodrive-upstream links pairs/<clip>/upstream/render_%d.png (1024x576,
  // frame 0 = the real image) as OUT/geodrive_upstream/sample_%06d/ with
  // OUT/geodrive_upstream/meta.jsonl; streetcrafter writes
  // pairs/<clip>/streetcrafter/ and OUT/streetcrafter/meta_info_*.json.
  std::vector<ExportFormat> exports;
  // The exports' split (val fraction by scene, seed).
  ExportOptions export_options;
  bool quiet = false;
  // The scene source this run uses (`geometry` with "auto" resolved).
  std::string SceneSourceName() const;
  // Throws InputError naming the bad option; changes nothing.
  void Check() const;
  // The options that affect the content of a pair, as a JSON object (stable key
  // order).
  std::string ContentOptionsJson() const;
  // The identity of the inputs, as a JSON object: the absolute dataroot and,
  // for a scene source that reads a folder, its absolute root (and map).
  // Recorded in each pair's meta.json options ("inputs", outside the options
  // hash); a pair of other inputs is never taken as built.
  std::string InputsJson() const;
};

// The id of the novel-view pair of `clip_id` at lateral offset `offset_m`
// (BuildDatasetOptions::lateral_offsets_m): "<clip>_shift_left_3m",
// "<clip>_shift_right_1p5m", "<clip>_shift_0m" (the magnitude in metres to
// the millimetre, trailing zeros dropped, the decimal point written "p").
std::string ShiftedPairId(const std::string& clip_id, double offset_m);

// `scene_from_cam` moved sideways: per frame, the camera's ego (through the
// camera's mounting `ego_from_cam`) moved by `offset_m` along the ego's own
// y axis (left positive), the camera with it:
// scene_from_cam[i] * cam_from_ego * T(0, offset_m, 0) * ego_from_cam. The
// scene must be metric (metres).
std::vector<Rigid3d> ShiftTrajectoryLaterally(
    const std::vector<Rigid3d>& scene_from_cam,
    const Rigid3d& ego_from_cam,
    double offset_m);

// Frame-0 figures of the pairs built in a run, averaged over the pairs that
// have them (meta.json `quality` has them per pair).
struct BuildQualityTotals {
  int pairs = 0;
  double coverage0_sum = 0;  // frame-0 condition coverage
  int psnr0_pairs = 0;
  double psnr0_sum = 0;  // frame-0 static-region PSNR (dB)
  // lidar-dense: support, completion and held-out accuracy.
  int completion_pairs = 0;
  double supported_sum = 0, coverage_of_supported_sum = 0;
  int holdout_pairs = 0;
  double mae_sum = 0, rmse_sum = 0, within_5_sum = 0, within_10_sum = 0;

  void Add(const PairQuality& quality);
  // "frame 0 of 3 pairs: coverage 0.736, static-region PSNR 32.3 dB; ..."
  // (empty when no pair was built).
  std::string BriefReport() const;
};

struct BuildDatasetSummary {
  int clips_total = 0;  // clips in this run's list (after --clips, shard, max)
  int built = 0;        // pairs built now
  int skipped_existing = 0;  // pairs already present and verified (resume)
  // Pairs rebuilt because a listed file was missing or had another size.
  int rebuilt_broken = 0;
  // Pairs built with other content options (another options_hash): rebuilt,
  // or kept with keep_mismatched.
  int rebuilt_mismatched = 0;
  int kept_mismatched = 0;
  // Pairs built from other inputs (another dataroot or scene-source root):
  // always rebuilt.
  int rebuilt_other_inputs = 0;
  // Lines that could not be appended to manifest/failures logs, and final
  // logs or report that could not be written (the run then fails, exit 3;
  // the logs are rebuilt from the pair folders at the end).
  int log_write_errors = 0;
  int skipped_no_monst3r =
      0;  // clips without a MonST3R folder (geometry monst3r)
  int failed = 0;
  bool interrupted = false;  // stopped by SIGINT/SIGTERM
  std::map<std::string, int> failures_by_stage;
  // Seconds per stage summed over clips: wall time under the stage's name,
  // the worker thread's CPU time under "cpu:<stage>" (geometry's includes the
  // LiDAR scale fit).
  std::map<std::string, double> seconds_by_stage;
  double seconds_total = 0;
  // Frame-0 quality of the pairs built in this run.
  BuildQualityTotals quality;
  std::string BriefReport() const;
};

// Runs the build. Per-clip failures are recorded in failures.jsonl and counted,
// never thrown; InputError is thrown for bad options or an unreadable dataset.
BuildDatasetSummary BuildDataset(BuildDatasetOptions options);

// Merges shard outputs in `out`: manifest.jsonl and failures.jsonl rebuilt
// (sorted by clip id) from the pair folders of the last run's clips, options
// and inputs (OUT/.run.json) and the shard failure logs, every export's index
// (with `export_options`' split: pass the shards' --val-fraction and
// --split-seed) and report.html written. Holds OUT/.lock exclusively.
// Returns the number of pairs.
int MergeBuildOutputs(const std::string& out,
                      const ExportOptions& export_options = {});

// `geodrive export`: adds `formats` to the pairs of the build-dataset output
// `out` (its manifest's pairs) as --export would have written them: each
// pair's clip is loaded again and its scene built and rendered with the
// pair's own options (meta.json), the exporters' files are written into the
// pair folder and its meta.json rewritten, then each format's index. Holds
// OUT/.lock exclusively. Returns the number of pairs; throws InputError
// naming the pair (a pair a format cannot serve, missing inputs).
int ExportPairs(const std::string& out,
                const std::vector<ExportFormat>& formats,
                const ExportOptions& options,
                bool quiet = false);

// Writes OUT/report.html: one self-contained page (inline CSS and script;
// links only to the pair files) with the counts, quality histograms, a
// sortable per-pair table, the failures with their messages, each pair's GT
// and condition videos side by side, and the time per stage. The same inputs
// give the same bytes.
void WriteBuildReport(const std::string& out,
                      const BuildDatasetSummary* summary);

}  // namespace geodrive
