#include "dataset/clips.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "dataset/clip_id.h"
#include "geometry/util/status.h"

namespace geodrive {

void ClipOptions::Check() const {
  GEODRIVE_CHECK_INPUT(!channel.empty(), "clip options: channel is empty");
  GEODRIVE_CHECK_INPUT(num_frames >= 1 && num_frames <= 100000,
                       "clip options: num_frames must be in [1, 100000], got ",
                       num_frames);
  GEODRIVE_CHECK_INPUT(stride >= 1, "clip options: stride must be >= 1, got ",
                       stride);
  GEODRIVE_CHECK_INPUT(
      target_rate_hz >= 0 && target_rate_hz <= 1000,
      "clip options: target_rate_hz must be in [0, 1000], got ",
      target_rate_hz);
  GEODRIVE_CHECK_INPUT(std::isfinite(max_time_error_s) && max_time_error_s > 0,
                       "clip options: max_time_error_s must be > 0");
  GEODRIVE_CHECK_INPUT(std::isfinite(max_gap_s) && max_gap_s >= 0,
                       "clip options: max_gap_s must be >= 0");
}

std::string ClipSelectionSummary::BriefReport() const {
  std::ostringstream os;
  os << clips << " clips from " << scenes << " scenes (" << scenes_too_short
     << " too short, " << dropped << " candidate starts dropped)";
  return os.str();
}

std::vector<ChainClip> SelectChainClips(const std::string& scene_name,
                                        const std::vector<int64_t>& ts,
                                        const std::vector<bool>& keyframes,
                                        const ClipOptions& options,
                                        ClipSelectionSummary* summary) {
  options.Check();
  GEODRIVE_CHECK_INPUT(keyframes.size() == ts.size(), "scene ", scene_name,
                       ": ", ts.size(), " timestamps but ", keyframes.size(),
                       " keyframe flags");
  std::vector<ChainClip> clips;
  if (summary) ++summary->scenes;
  const int n = static_cast<int>(ts.size());
  if (n < options.num_frames) {
    if (summary) ++summary->scenes_too_short;
    return clips;
  }
  const double max_gap_us = options.max_gap_s * 1e6;
  int next_allowed = 0;
  for (int start = 0; start < n; ++start) {
    // Candidate starts: every `stride` frames, or with start_at_keyframe the
    // first keyframe at least `stride` frames after the previous candidate.
    if (start < next_allowed) continue;
    if (options.start_at_keyframe && !keyframes[start]) continue;
    next_allowed = start + options.stride;
    std::vector<int> picks;
    picks.reserve(options.num_frames);
    bool ok = true;
    if (options.target_rate_hz == 0) {
      if (start + options.num_frames > n) break;
      for (int k = 0; k < options.num_frames; ++k) picks.push_back(start + k);
    } else {
      const double period_us = 1e6 / options.target_rate_hz;
      const double last_target =
          ts[start] + (options.num_frames - 1) * period_us;
      if (last_target > ts[n - 1] + options.max_time_error_s * 1e6) break;
      int j = start;
      for (int k = 0; k < options.num_frames && ok; ++k) {
        const double target = ts[start] + k * period_us;
        while (j + 1 < n &&
               std::abs(ts[j + 1] - target) < std::abs(ts[j] - target))
          ++j;
        if (std::abs(ts[j] - target) > options.max_time_error_s * 1e6)
          ok = false;
        if (!picks.empty() && picks.back() == j)
          ok = false;  // rate above the source rate
        picks.push_back(j);
      }
    }
    if (ok && max_gap_us > 0) {
      for (int i = picks.front(); i < picks.back() && ok; ++i) {
        if (ts[i + 1] - ts[i] > max_gap_us) ok = false;
      }
    }
    if (!ok) {
      if (summary) ++summary->dropped;
      continue;
    }
    ChainClip clip;
    clip.start_index = start;
    clip.resample_rate_hz = options.target_rate_hz;
    clip.id = MakeClipId(scene_name, start, options.target_rate_hz,
                         options.keyframes_only);
    for (int p : picks) {
      clip.frames.push_back(p);
      clip.timestamps.push_back(ts[p]);
    }
    clips.push_back(std::move(clip));
    if (summary) ++summary->clips;
  }
  return clips;
}

}  // namespace geodrive
