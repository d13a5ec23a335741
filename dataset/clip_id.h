#pragma once
// Clip identifiers shared by the nuScenes reader, the synthetic world's MonST3R
// folders and `geodrive build-dataset`: `<scene name>_<start index, 4
// digits>[_r<rate Hz>]`, where the start index is the position of the clip's
// first frame in the scene's CAM_FRONT sample_data chain (0-based, samples and
// sweeps together, ordered by timestamp). Example: "scene-0003_0012". The
// suffix appears only for clips resampled to a target rate (e.g. "_r10").
// Keyframe-only clips (2 Hz nuScenes samples) count the start in the scene's
// keyframe chain and end in "_kf", e.g. "scene-0916_0006_kf". Stable across
// runs: it depends only on the dataset contents.
//
// The scene name is data, and the clip id becomes a folder name: it goes
// through PathComponentFromName (geometry/util/names.h), so "../x" or "a/b"
// become "%2E.%2Fx" and "a%2Fb", and ordinary names stay as they are.

#include <cstdio>
#include <string>

#include "geometry/util/names.h"

namespace geodrive {

inline std::string MakeClipId(const std::string& scene_name,
                              int start_index,
                              int resample_rate_hz = 0,
                              bool keyframes = false) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "_%04d", start_index);
  std::string id = PathComponentFromName(scene_name, "scene name") + buf;
  if (resample_rate_hz > 0) id += "_r" + std::to_string(resample_rate_hz);
  if (keyframes) id += "_kf";
  return id;
}

}  // namespace geodrive
