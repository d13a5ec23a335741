#pragma once
// Writes the synthetic world (dataset/synthetic/synthetic_world.h) as a real
// nuScenes-format dataset (13 JSON tables, samples/ and sweeps/ with CAM_*
// JPEGs and LIDAR_TOP .pcd.bin, map masks) plus MonST3R-format outputs for
// 25-frame CAM_FRONT clips and a ground-truth sidecar per clip. Layout and
// conventions: docs/SYNTHETIC.md.
//
//   <out>/<version>/*.json                   13 nuScenes tables (JSON arrays)
//   <out>/samples/<CH>/<log>__<CH>__<us>.jpg  keyframes (and LIDAR_TOP
//   .pcd.bin) <out>/sweeps/<CH>/...                     non-keyframes
//   <out>/maps/<map token>.png                map masks
//   <out>/monst3r/<clip_id>/                  MonST3R demo output layout
//   (A.1-A.6) <out>/monst3r_gt/<clip_id>.json           true scale, poses,
//   intrinsics (never read by the <out>/monst3r_gt/<clip_id>/depth_%04d.npy
//   pipeline; tests only), true z-depth in metres <out>/synthetic_manifest.json
//   options, scenes, manoeuvres, clip ids
//
// Same options -> byte-identical files.

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "dataset/synthetic/synthetic_world.h"
#include "geometry/camera.h"
#include "geometry/rigid3.h"

namespace geodrive {

struct SyntheticDatasetOptions {
  // Number of scenes (one log each) and the world seed.
  int num_scenes = 2;
  uint64_t seed = 7;
  // Camera image size; intrinsics scale with it (fx = 1266.42 * W / 1600).
  int image_width = 1600, image_height = 900;
  // Camera channels to write (any of the six CAM_*). CAM_FRONT is needed for
  // MonST3R clips.
  std::vector<std::string> cameras = {"CAM_FRONT"};
  // Write MonST3R folders (and ground-truth sidecars) for CAM_FRONT clips.
  bool write_monst3r = false;
  // Metadata only: tables (and the map mask), no images, sweeps or MonST3R
  // outputs; lidar point counts and visibilities are then analytic estimates
  // (see docs/SYNTHETIC.md).
  bool tables_only = false;
  // Also write the five RADAR_* channels at 13 Hz (tables_only only; makes row
  // counts v1.0-trainval-like).
  bool radars = false;
  // Scene length in seconds; samples at 2 Hz: floor(2 * duration) keyframes.
  double scene_duration_s = 20.0;
  // Name of the table folder.
  std::string version = "v1.0-mini";
  // The brake-and-stop scenes reverse a few metres after the stop.
  bool reverse_after_stop = true;
  // LIDAR_TOP: 32 rings x this many azimuth steps per sweep.
  int lidar_azimuth_steps = 720;
  // JPEG quality of camera images (fixed -> deterministic).
  int jpeg_quality = 90;

  // ---- MonST3R outputs ----
  // CAM_FRONT frames between the starts of consecutive MonST3R clips (a
  // multiple of 6, so clips start at keyframes). 24: clips 0-24, 24-48, ...
  // (consecutive clips share one frame).
  int monst3r_clip_stride = 24;
  // At most this many clips per scene (0 = all that fit).
  int monst3r_max_clips_per_scene = 0;
  // MonST3R units per metre, drawn uniformly per clip (the unknown scale).
  double monst3r_scale_min = 0.05, monst3r_scale_max = 0.5;
  // Multiplicative depth noise (sigma, fraction of depth).
  double monst3r_depth_noise = 0.0;
  // Pose noise on frames 1..24 (frame 0 stays the world origin): rotation sigma
  // in degrees, translation sigma per axis in metres (applied before scaling).
  double monst3r_pose_noise_deg = 0.0, monst3r_pose_noise_m = 0.0;
  // Fraction of pixels whose depth is corrupted (x U(0.5, 2)); they get low
  // init_conf and -inf in conf_.
  double monst3r_outlier_fraction = 0.0;
  // Write the true depth (metres, 0 = sky) next to the sidecar.
  bool monst3r_write_true_depth = true;

  // Optional progress sink (one line per call).
  std::function<void(const std::string&)> progress;

  // Empty if valid, else the reason (one line).
  std::string Validate() const;
  bool Check() const { return Validate().empty(); }
};

struct SyntheticDatasetSummary {
  std::string root, version;
  int num_scenes = 0;
  int64_t num_samples = 0, num_sample_data = 0, num_ego_poses = 0;
  int64_t num_instances = 0, num_annotations = 0;
  int64_t num_images = 0, num_lidar_sweeps = 0, num_lidar_points = 0;
  std::vector<std::string> monst3r_clip_ids;
  std::vector<std::string> scene_maneuvers;  // per scene, e.g. "left-turn"
  double seconds = 0;

  std::string BriefReport() const;
};

// Writes the dataset into out_dir (created if needed; existing files are
// overwritten). Throws InputError on invalid options or unwritable paths.
SyntheticDatasetSummary WriteSyntheticDataset(
    const SyntheticDatasetOptions& options, const std::string& out_dir);

// ---- The synthetic rig and timeline (what the tables say, for tests and
// tools) ----

// Sample rate and sensor rates.
constexpr int kSyntheticSampleRateHz = 2, kSyntheticCameraRateHz = 12;
constexpr int kSyntheticLidarRateHz = 20, kSyntheticRadarRateHz = 13;
constexpr int kSyntheticClipLength = 25;

// All channel names, in the order used for tokens.
const std::vector<std::string>& SyntheticChannels();
bool IsCameraChannel(const std::string& channel);
// ego_from_sensor of a channel (nuScenes-like calibration).
Rigid3d SyntheticEgoFromSensor(const std::string& channel);
// Camera intrinsics at width x height. The principal point is chosen so that
// MonST3R's resize (ComputeMonst3rResizeSpec) puts it exactly at the processed
// image centre, which is where MonST3R assumes it (1600x900: cx = 801.0625, cy
// = 451.0625 -> 256, 144 at 512x288).
PinholeCamera SyntheticCameraIntrinsics(const std::string& channel,
                                        int width,
                                        int height);
// CAM_FRONT intrinsics after the MonST3R resize (cx = W/2, cy = H/2 up to
// rounding).
PinholeCamera SyntheticMonst3rCamera(int width, int height);

// Name and world of scene i ("scene-0001" for i = 0).
std::string SyntheticSceneName(int scene_index);
SyntheticWorldOptions SyntheticWorldOptionsFor(
    const SyntheticDatasetOptions& options, int scene_index);

// Timestamps (µs) of one scene.
struct SyntheticTimeline {
  int64_t start_us = 0;
  int num_samples = 0;
  std::vector<int64_t> sample_us;
  std::map<std::string, std::vector<int64_t>>
      channel_us;  // every written channel
  // Index of the sample a sample_data belongs to (keyframe: its own; else the
  // next one).
  std::map<std::string, std::vector<int>> channel_sample;
  std::map<std::string, std::vector<bool>> channel_key;
  // Seconds since the scene start.
  double Seconds(int64_t timestamp_us) const {
    return (timestamp_us - start_us) * 1e-6;
  }
};
SyntheticTimeline MakeSyntheticTimeline(const SyntheticDatasetOptions& options,
                                        int scene_index);
// CAM_FRONT start indices of the clips that get MonST3R folders.
std::vector<int> SyntheticMonst3rClipStarts(
    const SyntheticDatasetOptions& options, int num_cam_front_frames);

}  // namespace geodrive
