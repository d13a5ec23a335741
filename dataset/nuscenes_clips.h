#pragma once
// nuScenes clip selection: SelectChainClips (dataset/clips.h) over each
// scene's channel chain of sample_data, with the rows and scene kept.

#include <cstdint>
#include <string>
#include <vector>

#include "dataset/clips.h"
#include "dataset/nuscenes.h"

namespace geodrive {

struct Clip {
  std::string id;  // MakeClipId(scene name, start_index, target_rate_hz)
  int32_t scene = kNoIndex;
  int start_index = 0;  // index of the first frame in the scene's channel chain
  std::vector<int32_t>
      sample_data;  // rows of Nuscenes::sample_data(), in time order
  std::vector<int64_t> timestamps;  // microseconds
  int resample_rate_hz = 0;
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
