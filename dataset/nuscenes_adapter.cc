// The nuScenes adapter: Nuscenes tables + clip selection -> DriveClip.
//
// The only library file (with the reader itself, its projections and clip
// selection) that includes dataset/nuscenes.h. Poses are composed exactly as
// the devkit does (global_from_ego * ego_from_sensor), boxes are the
// devkit's interpolated boxes at each sample_data time, and the LiDAR
// provider is the scene's LIDAR_TOP chain (keyframes and sweeps).

#include <algorithm>
#include <map>
#include <memory>
#include <sstream>

#include "dataset/clips.h"
#include "dataset/drive_dataset.h"
#include "dataset/nuscenes.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

std::vector<ClipBox> ToClipBoxes(const Nuscenes& nusc, int32_t sd) {
  std::vector<ClipBox> out;
  for (const NuscenesBox& b : nusc.GetBoxes(sd)) {
    ClipBox c;
    if (b.instance != kNoIndex)
      c.instance_id = nusc.instances()[b.instance].token.ToString();
    if (b.category != kNoIndex) c.category = nusc.categories()[b.category].name;
    c.box = Box3d{b.center, b.wlh, b.orientation};
    out.push_back(std::move(c));
  }
  return out;
}

// The LIDAR_TOP chain of one scene.
class NuscenesLidar : public LidarProvider {
 public:
  NuscenesLidar(std::shared_ptr<const Nuscenes> nusc, std::vector<int32_t> rows)
      : nusc_(std::move(nusc)), rows_(std::move(rows)) {
    for (int32_t sd : rows_) {
      LidarSweepInfo info;
      info.relative_path = nusc_->sample_data()[sd].filename;
      info.timestamp_us = nusc_->sample_data()[sd].timestamp;
      info.world_from_ego = nusc_->GlobalFromEgo(sd);
      info.ego_from_sensor = nusc_->EgoFromSensor(sd);
      sweeps_.push_back(std::move(info));
    }
  }
  const std::vector<LidarSweepInfo>& Sweeps() const override { return sweeps_; }
  PointCloud Load(size_t index) const override {
    return nusc_->LoadLidar(rows_.at(index));
  }
  std::vector<ClipBox> Boxes(size_t index) const override {
    return ToClipBoxes(*nusc_, rows_.at(index));
  }
  // Index of sample_data row `sd` in the chain, if it is one of ours.
  std::optional<size_t> IndexOf(int32_t sd) const {
    const auto it = std::find(rows_.begin(), rows_.end(), sd);
    if (it == rows_.end()) return std::nullopt;
    return static_cast<size_t>(it - rows_.begin());
  }

 private:
  std::shared_ptr<const Nuscenes> nusc_;
  std::vector<int32_t> rows_;
  std::vector<LidarSweepInfo> sweeps_;
};

class NuscenesDriveDataset : public DriveDataset {
 public:
  explicit NuscenesDriveDataset(const DriveDatasetOptions& options)
      : options_(options) {
    NuscenesOptions no;
    no.dataroot = options.root;
    no.version = options.version;
    nusc_ = std::make_shared<const Nuscenes>(no);
    ClipOptions co;
    co.channel = options.channel;
    co.num_frames = options.clip_frames;
    co.stride = options.clip_stride;
    co.keyframes_only = options.frames == ClipFrameSource::kKeyframes;
    clips_ = SelectClips(*nusc_, co);
    for (size_t i = 0; i < clips_.size(); ++i) {
      ids_.push_back(clips_[i].id);
      by_id_[clips_[i].id] = i;
    }
    lidar_sensor_ = nusc_->FindSensor("LIDAR_TOP");
  }

  std::string Describe() const override {
    std::ostringstream os;
    os << "nuscenes " << options_.version << " at " << options_.root << ": "
       << nusc_->scenes().size() << " scenes, " << ids_.size() << " "
       << options_.clip_frames << "-frame " << options_.channel
       << (options_.frames == ClipFrameSource::kKeyframes ? " keyframe" : "")
       << " clips; " << nusc_->summary().BriefReport();
    return os.str();
  }
  const std::vector<std::string>& ClipIds() const override { return ids_; }
  bool HasLidar() const override { return lidar_sensor_ != kNoIndex; }

  DriveClip LoadClip(const std::string& id) const override {
    const auto it = by_id_.find(id);
    if (it == by_id_.end()) ThrowUnknownClip(id);
    const Clip& clip = clips_[it->second];
    const Nuscenes& nusc = *nusc_;
    DriveClip out;
    out.id = clip.id;
    out.dataset =
        "nuscenes " + options_.version + " at " + nusc.options().dataroot;
    out.scene_name = nusc.scenes()[clip.scene].name;
    out.scene_id = nusc.scenes()[clip.scene].token.ToString();
    out.channel = options_.channel;
    out.frame_source = options_.frames;
    out.units = "metres";
    std::shared_ptr<NuscenesLidar> lidar;
    if (HasLidar()) {
      // Keyframe clips use keyframe sweeps only (extracts without sweep
      // files have just those on disk).
      std::vector<int32_t> rows;
      for (int32_t sd : nusc.Chain(clip.scene, lidar_sensor_)) {
        if (options_.frames == ClipFrameSource::kAll ||
            nusc.sample_data()[sd].is_key_frame)
          rows.push_back(sd);
      }
      lidar = std::make_shared<NuscenesLidar>(nusc_, std::move(rows));
      out.lidar = lidar;
    }
    for (int32_t sd : clip.sample_data) {
      const NuscenesSampleData& row = nusc.sample_data()[sd];
      DriveFrame f;
      f.frame_id = row.token.ToString();
      f.relative_path = row.filename;
      f.image_path = nusc.DataPath(sd);
      f.timestamp_us = row.timestamp;
      f.is_keyframe = row.is_key_frame;
      f.world_from_ego = nusc.GlobalFromEgo(sd);
      f.ego_from_cam = nusc.EgoFromSensor(sd);
      f.world_from_cam = nusc.WorldFromSensor(sd);
      f.camera = nusc.Camera(sd);
      f.boxes = ToClipBoxes(nusc, sd);
      if (lidar && row.sample != kNoIndex) {
        const auto& sample = nusc.samples()[row.sample];
        if (lidar_sensor_ < static_cast<int32_t>(sample.data.size()) &&
            sample.data[lidar_sensor_] != kNoIndex)
          f.keyframe_sweep = lidar->IndexOf(sample.data[lidar_sensor_]);
      }
      out.frames.push_back(std::move(f));
    }
    out.provenance = {
        {"frames", options_.channel +
                       (options_.frames == ClipFrameSource::kKeyframes
                            ? " keyframe sample_data (2 Hz samples)"
                            : " sample_data (keyframes and sweeps)")},
        {"poses", "ego_pose.json * calibrated_sensor.json"},
        {"camera", "calibrated_sensor.json camera_intrinsic"},
        {"boxes",
         "sample_annotation.json, interpolated to each sample_data time"},
        {"lidar", !HasLidar() ? "none"
                  : options_.frames == ClipFrameSource::kKeyframes
                      ? "LIDAR_TOP keyframe sample_data of the scene"
                      : "LIDAR_TOP sample_data of the scene"}};
    return out;
  }

 private:
  [[noreturn]] void ThrowUnknownClip(const std::string& id) const {
    const auto slash = id.rfind('_');
    GEODRIVE_CHECK_INPUT(slash != std::string::npos, "'", id,
                         "' is not a clip id (<scene>_<start>)");
    GEODRIVE_CHECK_INPUT(nusc_->FindScene(id.substr(0, slash)) != kNoIndex,
                         "scene '", id.substr(0, slash), "' not found in ",
                         nusc_->VersionDir());
    ThrowInputError("'" + id + "'", "is not a ", options_.clip_frames,
                    "-frame clip of the dataset (stride ", options_.clip_stride,
                    "; see `geodrive nuscenes-info`)");
  }

  DriveDatasetOptions options_;
  std::shared_ptr<const Nuscenes> nusc_;
  std::vector<Clip> clips_;
  std::vector<std::string> ids_;
  std::map<std::string, size_t> by_id_;
  int32_t lidar_sensor_ = kNoIndex;
};

}  // namespace

std::string ToString(DatasetFormat format) {
  switch (format) {
    case DatasetFormat::kNuscenes:
      return "nuscenes";
  }
  return "nuscenes";
}

DatasetFormat ParseDatasetFormat(const std::string& text) {
  if (text == "nuscenes") return DatasetFormat::kNuscenes;
  throw InputError("unknown dataset format '" + text + "' (expected nuscenes)");
}

bool DriveDatasetOptions::Check() const {
  return !root.empty() && !version.empty() && !channel.empty() &&
         clip_frames >= 2 && clip_stride >= 1;
}

std::unique_ptr<DriveDataset> OpenDriveDataset(
    const DriveDatasetOptions& options) {
  GEODRIVE_CHECK_INPUT(options.Check(),
                       "dataset options: need a root, a version, a channel, "
                       "clip_frames >= 2 and clip_stride >= 1");
  switch (options.format) {
    case DatasetFormat::kNuscenes:
      return std::make_unique<NuscenesDriveDataset>(options);
  }
  throw InputError("unknown dataset format");
}

}  // namespace geodrive
