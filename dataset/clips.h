#pragma once
// Clip selection: runs of consecutive CAM_FRONT sample_data (samples and
// sweeps, 12 Hz) inside one scene, as Vista's 25-frame clips, with a stride
// between clip starts and optional resampling to a target rate (e.g. 10 Hz). A
// clip never crosses a scene boundary. Clip ids come from dataset/clip_id.h
// (MakeClipId) and depend only on the dataset contents.

#include <cstdint>
#include <string>
#include <vector>

#include "dataset/nuscenes.h"

namespace geodrive {

struct ClipOptions {
  std::string channel = "CAM_FRONT";
  // Only the channel's keyframes (samples, 2 Hz in nuScenes) instead of every
  // sample_data (keyframes and sweeps, 12 Hz): for extracts without sweep
  // files. Start indices then count keyframes and ids end in "_kf".
  bool keyframes_only = false;
  int num_frames = 25;  // frames per clip
  // Source frames between consecutive clip starts (6 = one keyframe interval at
  // 12 Hz).
  int stride = 6;
  // Only start clips on keyframes (Vista's clips start at a sample).
  bool start_at_keyframe = false;
  // 0 = consecutive source frames. Otherwise pick, for t_k = t_start + k /
  // rate, the source frame nearest in time (must be <= the source rate); the
  // clip id gets the suffix "_r<rate>".
  int target_rate_hz = 0;
  // With resampling: drop a clip if a chosen frame is further than this from
  // its target time (s).
  double max_time_error_s = 0.05;
  // Drop a clip whose consecutive frames are further apart than this (s); 0 =
  // no check.
  double max_gap_s = 0.0;
  void Check() const;
};

struct Clip {
  std::string id;  // MakeClipId(scene name, start_index, target_rate_hz)
  int32_t scene = kNoIndex;
  int start_index = 0;  // index of the first frame in the scene's channel chain
  std::vector<int32_t>
      sample_data;  // rows of Nuscenes::sample_data(), in time order
  std::vector<int64_t> timestamps;  // microseconds
  int resample_rate_hz = 0;
};

struct ClipSelectionSummary {
  int scenes = 0;            // scenes visited
  int scenes_too_short = 0;  // scenes whose chain is shorter than one clip
  int clips = 0;
  int dropped =
      0;  // candidate starts dropped (gaps, time error, keyframe rule)
  std::string BriefReport() const;
};

// All clips of all scenes, in scene then start order.
std::vector<Clip> SelectClips(const Nuscenes& nusc,
                              const ClipOptions& options,
                              ClipSelectionSummary* summary = nullptr);
// Clips of one scene.
std::vector<Clip> SelectSceneClips(const Nuscenes& nusc,
                                   int32_t scene,
                                   const ClipOptions& options,
                                   ClipSelectionSummary* summary = nullptr);

}  // namespace geodrive
