// nuScenes clip selection (dataset/nuscenes_clips.h).

#include "dataset/nuscenes_clips.h"

#include <set>

#include "geometry/util/names.h"
#include "geometry/util/status.h"

namespace geodrive {

std::vector<Clip> SelectSceneClips(const Nuscenes& nusc,
                                   int32_t scene,
                                   const ClipOptions& options,
                                   ClipSelectionSummary* summary) {
  options.Check();
  const int32_t sensor = nusc.FindSensor(options.channel);
  GEODRIVE_CHECK_INPUT(sensor != kNoIndex, nusc.VersionDir(),
                       "/sensor.json: no channel '", options.channel, "'");
  const auto& sd = nusc.sample_data();
  std::vector<int32_t> chain;
  for (int32_t row : nusc.Chain(scene, sensor))
    if (!options.keyframes_only || sd[row].is_key_frame) chain.push_back(row);
  std::vector<int64_t> ts;
  std::vector<bool> keyframes;
  for (int32_t row : chain) {
    ts.push_back(sd[row].timestamp);
    keyframes.push_back(sd[row].is_key_frame);
  }
  std::vector<Clip> clips;
  for (ChainClip& c : SelectChainClips(nusc.scenes()[scene].name, ts, keyframes,
                                       options, summary)) {
    Clip clip;
    clip.id = std::move(c.id);
    clip.scene = scene;
    clip.start_index = c.start_index;
    clip.resample_rate_hz = c.resample_rate_hz;
    for (int p : c.frames) clip.sample_data.push_back(chain[p]);
    clip.timestamps = std::move(c.timestamps);
    clips.push_back(std::move(clip));
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
                         c.id,
                         "' is produced by two scenes (two scenes share "
                         "a name and a token prefix)");
  }
  return clips;
}

}  // namespace geodrive
