#pragma once
// DriveDataset: a driving dataset as a list of clips (dataset/drive_clip.h).
// One implementation per dataset format, one factory (OpenDriveDataset); only
// the adapter knows the dataset's tables. Adding a dataset: a new
// `dataset/<name>_adapter.cc` implementing DriveDataset, an enum value in
// DatasetFormat and one case in OpenDriveDataset (docs/ARCHITECTURE.md).

#include <memory>
#include <string>
#include <vector>

#include "dataset/drive_clip.h"

namespace geodrive {

enum class DatasetFormat {
  kNuscenes,  // nuScenes tables (v1.0-*), samples/ and sweeps/
  kWaymo,     // Waymo Open Dataset v1: *.tfrecord segments of Frame protos
};
std::string ToString(DatasetFormat format);
// "nuscenes" or "waymo"; throws InputError naming the accepted values
// otherwise.
DatasetFormat ParseDatasetFormat(const std::string& text);
// The format of the dataset at `root`: kWaymo for a .tfrecord file or a
// folder holding *.tfrecord files, else kNuscenes.
DatasetFormat DetectDatasetFormat(const std::string& root);
// ParseDatasetFormat(text), or DetectDatasetFormat(root) for "auto" or "".
DatasetFormat ResolveDatasetFormat(const std::string& text,
                                   const std::string& root);

struct DriveDatasetOptions {
  // Dataset format.
  DatasetFormat format = DatasetFormat::kNuscenes;
  // Dataset root (nuScenes: the folder holding <version>/, samples/, sweeps/;
  // Waymo: a folder of *.tfrecord segments, or one .tfrecord file).
  std::string root;
  // Table version (nuScenes: v1.0-mini, v1.0-trainval, ...; unused by Waymo).
  std::string version = "v1.0-mini";
  // Camera channel whose frames make the clips (the reference camera).
  // Waymo: its camera names (FRONT, FRONT_LEFT, ...); "CAM_FRONT" and the
  // like are read as "FRONT".
  std::string channel = "CAM_FRONT";
  // Surround view: the cameras every clip carries (DriveClip::rig), the
  // reference `channel` among them (put first); {"all"} = every camera of the
  // dataset. Each reference frame is matched, per camera, to that camera's
  // frame of the same sample (keyframes) or the one nearest in time (within
  // kMaxRigTimeGapUs). Empty = single-camera clips.
  std::vector<std::string> cameras;
  // Every frame of the channel, or only its keyframes (for extracts without
  // sweep files; clip ids then end in "_kf").
  ClipFrameSource frames = ClipFrameSource::kAll;
  // Frames per clip.
  int clip_frames = 25;
  // Source frames between consecutive clip starts (6 = one keyframe interval
  // of nuScenes' 12 Hz camera; Waymo frames are 10 Hz).
  int clip_stride = 6;
  // True if the options are usable (root set, clip_frames >= 1, stride >= 1).
  bool Check() const;
};

// Largest time between a reference frame and a rig camera's matched frame
// (nuScenes' six cameras fire within 43 ms of each other).
constexpr int64_t kMaxRigTimeGapUs = 60000;

// The nuScenes camera channels in the rig's layout order: the front row left
// to right, then the back row left to right (as the mosaic shows them).
const std::vector<std::string>& NuscenesRigLayout();
// "all" or "A,B,..." -> the camera list of DriveDatasetOptions::cameras
// (trimmed, no duplicates; `reference`, when not empty, must be listed and is
// moved first). Throws InputError naming `option` for an empty name, a
// duplicate or a missing reference.
std::vector<std::string> ParseCameraList(const std::string& text,
                                         const std::string& reference,
                                         const std::string& option);

class DriveDataset {
 public:
  virtual ~DriveDataset() = default;
  // One line: format, version, root, scene and clip counts.
  virtual std::string Describe() const = 0;
  // Clip ids in dataset order (scene, then start frame).
  virtual const std::vector<std::string>& ClipIds() const = 0;
  // True if the dataset has a LiDAR (clips then carry a LidarProvider).
  virtual bool HasLidar() const = 0;
  // The clip `id`: frames, poses, cameras, boxes, LiDAR provider (metadata
  // only: images and sweeps are read when used). The clip may be used after
  // the dataset is destroyed. Throws InputError for an unknown id or
  // inconsistent tables (naming the table and record).
  virtual DriveClip LoadClip(const std::string& id) const = 0;
};

// Opens a dataset (reads its tables). Throws InputError naming the file and
// the problem.
std::unique_ptr<DriveDataset> OpenDriveDataset(
    const DriveDatasetOptions& options);

}  // namespace geodrive
