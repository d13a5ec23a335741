#pragma once
// Clip selection, dataset-generic: runs of consecutive frames of one camera
// (nuScenes CAM_FRONT sample_data, 12 Hz; Waymo FRONT, 10 Hz) inside one scene,
// as Vista's 25-frame clips, with a stride between clip starts and optional
// resampling to a target rate (e.g. 10 Hz). A clip never crosses a scene
// boundary. Clip ids come from dataset/clip_id.h (MakeClipId) and depend only
// on the dataset contents.

#include <cstdint>
#include <string>
#include <vector>

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

struct ClipSelectionSummary {
  int scenes = 0;            // scenes visited
  int scenes_too_short = 0;  // scenes whose chain is shorter than one clip
  int clips = 0;
  int dropped =
      0;  // candidate starts dropped (gaps, time error, keyframe rule)
  std::string BriefReport() const;
};

// One clip of a frame chain (SelectChainClips).
struct ChainClip {
  std::string id;       // MakeClipId(scene name, start_index, rate, keyframes)
  int start_index = 0;  // index of the first frame in the chain
  std::vector<int> frames;          // chain indices, in time order
  std::vector<int64_t> timestamps;  // microseconds
  int resample_rate_hz = 0;
};

// The clips of one scene's frame chain (the reference camera's frames in time
// order: `timestamps` in microseconds, `keyframes` whether each is an
// annotated keyframe, same length). With options.keyframes_only the caller
// passes the keyframe chain. Dataset-generic: adapters build the chain from
// their own tables.
std::vector<ChainClip> SelectChainClips(
    const std::string& scene_name,
    const std::vector<int64_t>& timestamps,
    const std::vector<bool>& keyframes,
    const ClipOptions& options,
    ClipSelectionSummary* summary = nullptr);

}  // namespace geodrive
