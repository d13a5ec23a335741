// The nuScenes adapter: Nuscenes tables + clip selection -> DriveClip.
//
// The only library file (with the reader itself, its projections and clip
// selection) that includes dataset/nuscenes.h. Poses are composed exactly as
// the devkit does (global_from_ego * ego_from_sensor), boxes are the
// devkit's interpolated boxes at each sample_data time, and the LiDAR
// provider is the scene's LIDAR_TOP chain (keyframes and sweeps).

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>

#include "dataset/drive_dataset.h"
#include "dataset/internal/adapters.h"
#include "dataset/nuscenes.h"
#include "dataset/nuscenes_clips.h"
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
    ResolveRig();
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
    for (int32_t sd : clip.sample_data)
      out.frames.push_back(MakeFrame(sd, lidar.get()));
    if (!rig_sensors_.empty()) out.rig = LoadRig(clip, out, lidar.get());
    out.provenance = {
        {"frames",
         options_.channel + (options_.frames == ClipFrameSource::kKeyframes
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
  DriveFrame MakeFrame(int32_t sd, const NuscenesLidar* lidar) const {
    const Nuscenes& nusc = *nusc_;
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
    return f;
  }

  // The rig cameras' frames matched to the reference frames: the same
  // sample's frame for keyframe clips, the nearest in time otherwise.
  std::vector<CameraStream> LoadRig(const Clip& clip,
                                    const DriveClip& reference,
                                    const NuscenesLidar* lidar) const {
    const Nuscenes& nusc = *nusc_;
    std::vector<CameraStream> rig;
    for (size_t k = 0; k < rig_sensors_.size(); ++k) {
      const int32_t sensor = rig_sensors_[k];
      CameraStream stream;
      stream.channel = rig_channels_[k];
      if (stream.channel == options_.channel) {
        stream.frames = reference.frames;
        rig.push_back(std::move(stream));
        continue;
      }
      const std::vector<int32_t>& chain = nusc.Chain(clip.scene, sensor);
      for (size_t i = 0; i < clip.sample_data.size(); ++i) {
        const int32_t ref = clip.sample_data[i];
        const int32_t sd = MatchFrame(ref, sensor, chain);
        const int64_t gap = std::llabs(nusc.sample_data()[sd].timestamp -
                                       nusc.sample_data()[ref].timestamp);
        GEODRIVE_CHECK_INPUT(
            gap <= kMaxRigTimeGapUs, clip.id, ": ", stream.channel,
            " has no frame within ", kMaxRigTimeGapUs / 1000, " ms of ",
            options_.channel, " frame ", i, " (nearest ", gap / 1000, " ms)");
        stream.frames.push_back(MakeFrame(sd, lidar));
      }
      rig.push_back(std::move(stream));
    }
    return rig;
  }

  // The frame of `sensor` for reference frame `ref`: the same sample's
  // (keyframes), else the nearest in time on the camera's chain.
  int32_t MatchFrame(int32_t ref,
                     int32_t sensor,
                     const std::vector<int32_t>& chain) const {
    const Nuscenes& nusc = *nusc_;
    const NuscenesSampleData& row = nusc.sample_data()[ref];
    if (row.is_key_frame && row.sample != kNoIndex) {
      const auto& data = nusc.samples()[row.sample].data;
      if (sensor < static_cast<int32_t>(data.size()) &&
          data[sensor] != kNoIndex)
        return data[sensor];
    }
    GEODRIVE_CHECK_INPUT(!chain.empty(), nusc.VersionDir(), ": scene has no ",
                         nusc.sensors()[sensor].channel, " sample_data");
    const auto it = std::lower_bound(
        chain.begin(), chain.end(), row.timestamp, [&](int32_t sd, int64_t t) {
          return nusc.sample_data()[sd].timestamp < t;
        });
    int32_t best = it == chain.end() ? chain.back() : *it;
    if (it != chain.begin()) {
      const int32_t before = *(it - 1);
      if (std::llabs(nusc.sample_data()[before].timestamp - row.timestamp) <=
          std::llabs(nusc.sample_data()[best].timestamp - row.timestamp))
        best = before;
    }
    return best;
  }

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

  // The rig's sensors from options_.cameras ("all": every camera channel of
  // the tables, in NuscenesRigLayout() order, then any others by name).
  void ResolveRig() {
    if (options_.cameras.empty()) return;
    std::vector<std::string> names = options_.cameras;
    if (names.size() == 1 && names[0] == "all") {
      names.clear();
      for (const std::string& c : NuscenesRigLayout())
        if (nusc_->FindSensor(c) != kNoIndex) names.push_back(c);
      std::vector<std::string> others;
      for (const NuscenesSensor& s : nusc_->sensors())
        if (s.modality == SensorModality::kCamera &&
            std::find(names.begin(), names.end(), s.channel) == names.end())
          others.push_back(s.channel);
      std::sort(others.begin(), others.end());
      names.insert(names.end(), others.begin(), others.end());
      const auto ref = std::find(names.begin(), names.end(), options_.channel);
      if (ref != names.end()) std::rotate(names.begin(), ref, ref + 1);
    }
    for (const std::string& name : names) {
      const int32_t sensor = nusc_->FindSensor(name);
      GEODRIVE_CHECK_INPUT(sensor != kNoIndex,
                           "--cameras: ", nusc_->VersionDir(),
                           " has no sensor '", name, "'");
      GEODRIVE_CHECK_INPUT(
          nusc_->sensors()[sensor].modality == SensorModality::kCamera,
          "--cameras: '", name, "' is a ",
          ToString(nusc_->sensors()[sensor].modality), ", not a camera");
      rig_sensors_.push_back(sensor);
      rig_channels_.push_back(name);
    }
    GEODRIVE_CHECK_INPUT(
        !rig_channels_.empty() && rig_channels_.front() == options_.channel,
        "--cameras: the list must hold the reference camera ",
        options_.channel);
  }

  DriveDatasetOptions options_;
  std::vector<int32_t> rig_sensors_;
  std::vector<std::string> rig_channels_;
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
    case DatasetFormat::kWaymo:
      return "waymo";
  }
  return "nuscenes";
}

DatasetFormat ParseDatasetFormat(const std::string& text) {
  if (text == "nuscenes") return DatasetFormat::kNuscenes;
  if (text == "waymo") return DatasetFormat::kWaymo;
  throw InputError("unknown dataset format '" + text +
                   "' (expected nuscenes or waymo)");
}

DatasetFormat DetectDatasetFormat(const std::string& root) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_regular_file(root, ec))
    return fs::path(root).extension() == ".tfrecord" ? DatasetFormat::kWaymo
                                                     : DatasetFormat::kNuscenes;
  if (!fs::is_directory(root, ec)) return DatasetFormat::kNuscenes;
  for (const auto& e : fs::directory_iterator(root, ec))
    if (e.path().extension() == ".tfrecord") return DatasetFormat::kWaymo;
  return DatasetFormat::kNuscenes;
}

DatasetFormat ResolveDatasetFormat(const std::string& text,
                                   const std::string& root) {
  return text.empty() || text == "auto" ? DetectDatasetFormat(root)
                                        : ParseDatasetFormat(text);
}

const std::vector<std::string>& NuscenesRigLayout() {
  static const std::vector<std::string> layout = {
      "CAM_FRONT_LEFT", "CAM_FRONT", "CAM_FRONT_RIGHT",
      "CAM_BACK_LEFT",  "CAM_BACK",  "CAM_BACK_RIGHT"};
  return layout;
}

std::vector<std::string> ParseCameraList(const std::string& text,
                                         const std::string& reference,
                                         const std::string& option) {
  if (text == "all") return {"all"};
  std::vector<std::string> names;
  size_t start = 0;
  while (start <= text.size()) {
    size_t end = text.find(',', start);
    if (end == std::string::npos) end = text.size();
    std::string name = text.substr(start, end - start);
    name.erase(0, name.find_first_not_of(" \t"));
    name.erase(name.find_last_not_of(" \t") + 1);
    GEODRIVE_CHECK_INPUT(!name.empty(), option, " '", text,
                         "': an empty camera name (expected all or "
                         "CAM_FRONT,CAM_FRONT_LEFT,...)");
    GEODRIVE_CHECK_INPUT(
        std::find(names.begin(), names.end(), name) == names.end(), option,
        " '", text, "': camera ", name, " is listed twice");
    names.push_back(std::move(name));
    start = end + 1;
  }
  if (reference.empty()) return names;
  const auto ref = std::find(names.begin(), names.end(), reference);
  GEODRIVE_CHECK_INPUT(ref != names.end(), option, " '", text,
                       "': the list must hold the reference camera ",
                       reference);
  std::rotate(names.begin(), ref, ref + 1);
  return names;
}

bool DriveDatasetOptions::Check() const {
  return !root.empty() && !version.empty() && !channel.empty() &&
         clip_frames >= 1 && clip_stride >= 1;
}

std::unique_ptr<DriveDataset> OpenDriveDataset(
    const DriveDatasetOptions& options) {
  GEODRIVE_CHECK_INPUT(options.Check(),
                       "dataset options: need a root, a version, a channel, "
                       "clip_frames >= 1 and clip_stride >= 1");
  switch (options.format) {
    case DatasetFormat::kNuscenes:
      return std::make_unique<NuscenesDriveDataset>(options);
    case DatasetFormat::kWaymo:
      return OpenWaymoDriveDataset(options);
  }
  throw InputError("unknown dataset format");
}

}  // namespace geodrive
