#include "dataset/clips.h"

#include <algorithm>
#include <cmath>
#include <set>
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

std::vector<Clip> SelectSceneClips(const Nuscenes& nusc,
                                   int32_t scene,
                                   const ClipOptions& options,
                                   ClipSelectionSummary* summary) {
  options.Check();
  std::vector<Clip> clips;
  const int32_t sensor = nusc.FindSensor(options.channel);
  GEODRIVE_CHECK_INPUT(sensor != kNoIndex, nusc.VersionDir(),
                       "/sensor.json: no channel '", options.channel, "'");
  const auto& sd = nusc.sample_data();
  std::vector<int32_t> keyframes;
  if (options.keyframes_only) {
    for (int32_t row : nusc.Chain(scene, sensor))
      if (sd[row].is_key_frame) keyframes.push_back(row);
  }
  const std::vector<int32_t>& chain =
      options.keyframes_only ? keyframes : nusc.Chain(scene, sensor);
  if (summary) ++summary->scenes;
  const int n = static_cast<int>(chain.size());
  if (n < options.num_frames) {
    if (summary) ++summary->scenes_too_short;
    return clips;
  }
  const std::string& scene_name = nusc.scenes()[scene].name;
  std::vector<int64_t> ts(n);
  for (int i = 0; i < n; ++i) ts[i] = sd[chain[i]].timestamp;
  const double max_gap_us = options.max_gap_s * 1e6;
  int next_allowed = 0;
  for (int start = 0; start < n; ++start) {
    // Candidate starts: every `stride` frames, or with start_at_keyframe the
    // first keyframe at least `stride` frames after the previous candidate.
    if (start < next_allowed) continue;
    if (options.start_at_keyframe && !sd[chain[start]].is_key_frame) continue;
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
    Clip clip;
    clip.scene = scene;
    clip.start_index = start;
    clip.resample_rate_hz = options.target_rate_hz;
    clip.id = MakeClipId(scene_name, start, options.target_rate_hz,
                         options.keyframes_only);
    for (int p : picks) {
      clip.sample_data.push_back(chain[p]);
      clip.timestamps.push_back(ts[p]);
    }
    clips.push_back(std::move(clip));
    if (summary) ++summary->clips;
  }
  return clips;
}

std::vector<Clip> SelectClips(const Nuscenes& nusc,
                              const ClipOptions& options,
                              ClipSelectionSummary* summary) {
  std::vector<Clip> clips;
  // Clip ids are unique per run: a scene whose name an earlier scene already
  // has gets its clips named "<name>~<first 8 characters of its token>_..."
  // (stable: it depends only on the tables), never the other scene's folder.
  std::set<std::string> names_seen;
  for (size_t s = 0; s < nusc.scenes().size(); ++s) {
    auto scene_clips =
        SelectSceneClips(nusc, static_cast<int32_t>(s), options, summary);
    const auto& scene = nusc.scenes()[s];
    if (!names_seen.insert(scene.name).second) {
      const std::string plain = PathComponentFromName(scene.name, "scene name");
      // '~' never comes out of PathComponentFromName for a name's own bytes.
      const std::string unique =
          plain + "~" + scene.token.ToString().substr(0, 8);
      for (auto& c : scene_clips) c.id = unique + c.id.substr(plain.size());
    }
    for (auto& c : scene_clips) clips.push_back(std::move(c));
  }
  std::set<std::string> ids;
  for (const auto& c : clips) {
    GEODRIVE_CHECK_INPUT(ids.insert(c.id).second, "scene tables: clip id '",
                         c.id, "' is produced by two scenes (two scenes share "
                         "a name and a token prefix)");
  }
  return clips;
}

}  // namespace geodrive
