#pragma once
// Training pairs written by `geodrive build-dataset` and read by the diffusion
// runtime.
//
// Layout of a build output OUT/:
//   pairs/<clip_id>/{gt.mp4, cond.mp4, first_frame.png, boxes.json, meta.json,
//   preview.png} manifest.jsonl   one line per finished pair (schema
//   data_schema/manifest_line.schema.json) failures.jsonl   one line per failed
//   clip: {"clip_id", "stage", "error"}
// meta.json follows data_schema/pair_meta.schema.json. Pairs are written to
// pairs/.tmp-<clip_id>/ and renamed when complete, so a pair folder either is
// whole or absent.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/rigid3.h"

namespace geodrive {

struct PairFrame {
  std::string sample_data_token;
  int64_t timestamp_us = 0;
  std::string filename;  // relative to the dataroot
};

struct PairQuality {
  // Fraction of valid condition pixels per frame.
  std::vector<double> coverage;
  // Reprojection RMS (px) over static pixels before and after the pose
  // refinement (paper eq. 3); absent when the refinement did not run.
  std::optional<double> reprojection_rms_px_before;
  std::optional<double> reprojection_rms_px_after;
  // Frame-0 depth completion (lidar-dense): the fraction of the image the
  // LiDAR supports (below the envelope of its returns) and the fraction of
  // that area with a completed depth.
  std::optional<double> supported_fraction;
  std::optional<double> coverage_of_supported;
  // Frame-0 depth completion (lidar-dense) on held-out returns of the frame-0
  // sweep (a seeded 20 %): how many, how many the completion covered, MAE and
  // RMSE (metres), fractions within 5 % and 10 % of the held-out depth.
  struct HoldOut {
    int64_t held_out = 0;
    int64_t covered = 0;
    double mae_m = 0, rmse_m = 0;
    double within_5_percent = 0, within_10_percent = 0;
  };
  std::optional<HoldOut> completion_holdout;
  // Inlier fraction of the LiDAR scale fit; absent when there was none.
  std::optional<double> scale_inlier_fraction;
  // Condition vs GT PSNR (dB) over the static rendered pixels per frame;
  // nullopt (JSON null) for a frame with no such pixel.
  std::vector<std::optional<double>> psnr_static;
};

// Surround view: one camera of a rig pair (its videos, frames, poses and
// quality).
struct PairView {
  // Camera channel, e.g. "CAM_FRONT_LEFT".
  std::string channel;
  std::vector<PairFrame> frames;
  PinholeCamera intrinsics;  // at the output size
  // Per frame, in the pair's world (the reference camera at frame 0).
  std::vector<Rigid3d> world_from_cam;
  // Condition coverage and static-region PSNR per frame; lidar-dense: the
  // frame-0 supported fraction and the completed fraction of it.
  std::vector<double> coverage;
  std::vector<std::optional<double>> psnr_static;
  std::optional<double> supported_fraction;
  std::optional<double> coverage_of_supported;
  // Points the view's scene built, and how many the rig fusion kept.
  int64_t points_built = 0, points_kept = 0;
  // role ("gt", "cond", "boxes") -> file name inside the pair folder.
  std::map<std::string, std::string> files;
};

// Surround view: frame-0 rendered-depth agreement of two overlapping cameras
// (dataset/rig.h RigSeamAgreement).
struct PairSeam {
  std::string camera_a, camera_b;
  int64_t overlap_pixels = 0;
  // Fraction of the overlap pixels whose depths agree within 1 %.
  double agreeing_fraction = 0;
};

// A novel-view pair (build-dataset lateral offsets, `geodrive nvs-set`): the
// condition rendered along the source clip's camera trajectory shifted
// sideways, the ground truth the clip's real frames.
struct PairNovelView {
  // The dataset clip the pair was made from (the pair's clip_id is
  // <source clip>_shift_<left|right>_<offset>m).
  std::string source_clip_id;
  // Sideways offset of every frame's ego pose along that pose's own y axis
  // (metres; ego frame x forward, y left, z up: positive = left).
  double lateral_offset_m = 0;
};

struct PairMeta {
  std::string clip_id;
  std::string scene_name;
  std::string scene_token;
  std::vector<PairFrame> frames;
  // Which frames make the clip: "all" (keyframes and sweeps) or "keyframes";
  // and the median time between consecutive frames (s), 0 when unknown (old
  // metas without the field).
  std::string frame_source = "all";
  double frame_interval_s = 0;
  // With --export geodrive-upstream: the clip's index in the dataset's clip
  // list (upstream scene_idx / sample_%06d); the frames are files.upstream.
  std::optional<int> upstream_scene_idx;
  double fps = 10.0;
  PinholeCamera intrinsics;  // at the output size
  std::string resize_mode;   // "resize" or "center-crop"
  std::vector<Rigid3d>
      world_from_cam;  // per frame, world = first camera unless said otherwise
  std::string pose_units;  // "metres" or "monst3r"
  double scale = 1.0;  // metres per MonST3R unit (1 when pose_units is metres)
  std::string scale_source;     // "lidar", "ego", "none"
  std::string scale_report;     // human-readable summary of the scale fit
  std::string geometry_source;  // "monst3r" or "lidar"
  std::string preset;           // "paper" or "geodrive-compat"
  std::string edit_mode;        // "3d", "2d" or "none"
  std::string options_json;  // the effective options as a JSON object (string)
  std::string options_hash;  // 16 hex digits of a hash of options_json
  std::string tool_version;
  PairQuality quality;
  std::map<std::string, std::string>
      files;  // role -> file name inside the pair folder
  // Size in bytes of each regular file of `files` (meta.json aside): a resume
  // rebuilds a pair whose files do not match.
  std::map<std::string, uint64_t> file_sizes;
  // Surround view: every camera, the reference first (whose videos are also
  // files.gt / files.cond, and whose frames and poses are the fields above);
  // empty for a single-camera pair.
  std::vector<PairView> views;
  // Surround view: the seam check of every overlapping camera pair.
  std::vector<PairSeam> seams;
  // A novel-view pair: its source clip and offset (world_from_cam is then
  // the shifted trajectory the condition was rendered along; the frames are
  // the source clip's). Absent for a pair along the recorded trajectory.
  std::optional<PairNovelView> novel_view;
};

// Serialises to / parses from the meta.json text. Parse errors throw InputError
// naming `what`.
std::string PairMetaToJson(const PairMeta& meta);
PairMeta PairMetaFromJson(const std::string& text,
                          const std::string& what = "meta.json");
PairMeta ReadPairMeta(const std::string& pair_dir);

struct ManifestEntry {
  std::string clip_id;
  std::string pair_dir;  // relative to the build output, "pairs/<clip_id>"
  std::string scene_name;
  int num_frames = 0;
  std::string geometry_source;
  std::string pose_units;
  double mean_coverage = 0;
  std::string options_hash;
  // Surround view: the pair's cameras (reference first); empty for a
  // single-camera pair (the line then has no "cameras").
  std::vector<std::string> cameras;
};
std::string ManifestEntryToJson(const ManifestEntry& entry);
ManifestEntry ManifestEntryFromJson(const std::string& line,
                                    const std::string& what);
// Reads every line of a manifest.jsonl; throws InputError naming the file and
// line on bad JSON.
std::vector<ManifestEntry> ReadManifest(const std::string& path);

// One pair of a build output, resolved for reading: its metadata and the
// paths of the GT and condition videos (the lossless frame folders
// gt_frames/ cond_frames/ when the pair has them, else gt.mp4 / cond.mp4).
struct PairRecord {
  ManifestEntry entry;
  PairMeta meta;
  std::string dir;         // build_dir + "/" + entry.pair_dir
  std::string gt_video;    // video file or frame folder
  std::string cond_video;  // video file or frame folder
  // Surround view: per camera (meta.views order) the GT and condition
  // videos; empty for a single-camera pair.
  std::vector<std::string> view_gt_videos, view_cond_videos;
};
// Resolves a manifest entry under `build_dir` (the folder of manifest.jsonl).
// Throws InputError naming the file when pair_dir or a file name escapes the
// build folder (absolute, "..", or a file name with '/'), meta.json is bad or
// its clip id differs from the manifest's, or a video is missing.
PairRecord ReadPair(const std::string& build_dir, const ManifestEntry& entry);

struct FailureEntry {
  std::string clip_id;
  std::string stage;
  std::string error;
};
std::string FailureEntryToJson(const FailureEntry& entry);
std::vector<FailureEntry> ReadFailures(const std::string& path);

}  // namespace geodrive
