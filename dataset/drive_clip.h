#pragma once
// DriveClip: what a dataset adapter hands to the rest of the toolkit for one
// clip -- per frame the image, its time, its pose and camera, the 3D boxes
// seen then, and a LiDAR provider -- with no dataset types in it. Adapters
// (dataset/drive_dataset.h: nuScenes today; Waymo, KITTI, "a folder of images
// and a trajectory" later) fill it; scene sources (dataset/scene_source.h)
// and the pair builder read it.
//
// Frames: `world` is the dataset's global frame, in metres; camera axes are
// OpenCV (x right, y down, z forward); world_from_cam = world_from_ego *
// ego_from_cam (both kept, so that LiDAR-to-camera chains can be composed as
// the dataset's own tools do: sensor -> ego at LiDAR time -> world -> ego at
// camera time -> camera).

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "geometry/box3d.h"
#include "geometry/camera.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"

namespace geodrive {

// Which of a camera's frames make clips.
enum class ClipFrameSource {
  kAll,        // every frame (nuScenes: keyframes and sweeps, 12 Hz)
  kKeyframes,  // annotated keyframes only (nuScenes samples, 2 Hz)
};
std::string ToString(ClipFrameSource source);  // "all" / "keyframes"
// Parses "all" or "keyframes"; throws InputError otherwise.
ClipFrameSource ParseClipFrameSource(const std::string& text);

// One annotated object in one frame (or LiDAR sweep).
struct ClipBox {
  // Stable instance id across frames (nuScenes: the instance token).
  std::string instance_id;
  // Category name, e.g. "vehicle.car"; empty when the dataset has none.
  std::string category;
  // The box in the world frame (metres).
  Box3d box;
};

struct DriveFrame {
  // The dataset's id of the frame (nuScenes: the sample_data token).
  std::string frame_id;
  // Image path relative to the dataset root (as the dataset lists it).
  std::string relative_path;
  // Image path to open (root joined with relative_path).
  std::string image_path;
  // Capture time, microseconds (dataset clock).
  int64_t timestamp_us = 0;
  // True if the frame is an annotated keyframe.
  bool is_keyframe = false;
  // Ego pose at the frame's time and the camera's mounting.
  Rigid3d world_from_ego;
  Rigid3d ego_from_cam;
  // = world_from_ego * ego_from_cam.
  Rigid3d world_from_cam;
  // Pinhole camera at the source image size (integer-index pixels).
  PinholeCamera camera;
  // Boxes annotated (or interpolated) at the frame's time.
  std::vector<ClipBox> boxes;
  // The LiDAR sweep of the same keyframe sample (index into the provider's
  // Sweeps()), when the dataset pairs them.
  std::optional<size_t> keyframe_sweep;
};

// Metadata of one LiDAR sweep; Load() reads its points.
struct LidarSweepInfo {
  // Sweep file, relative to the dataset root (for messages and provenance).
  std::string relative_path;
  int64_t timestamp_us = 0;
  Rigid3d world_from_ego;   // ego pose at the sweep time
  Rigid3d ego_from_sensor;  // LiDAR mounting
  // = world_from_ego * ego_from_sensor.
  Rigid3d WorldFromSensor() const { return world_from_ego * ego_from_sensor; }
};

// The LiDAR sweeps of a clip's scene, in time order. Points are read on
// demand. Implementations are thread-safe for concurrent const calls.
class LidarProvider {
 public:
  virtual ~LidarProvider() = default;
  // Every sweep of the scene, sorted by timestamp.
  virtual const std::vector<LidarSweepInfo>& Sweeps() const = 0;
  // Points of sweep `index` in the sensor frame (x, y, z, intensity, ring).
  // Throws InputError naming the file when it is missing or malformed.
  virtual PointCloud Load(size_t index) const = 0;
  // Boxes at the sweep's time (world frame), for removing moving objects.
  virtual std::vector<ClipBox> Boxes(size_t index) const = 0;
  // Sweep `index`'s static returns in the world frame: Load's points less the
  // ego vehicle's own (within kEgoReturnRadiusM of the sensor, horizontally)
  // and those within kBoxMarginM of a box at the sweep's time (Boxes).
  // Computed each call; a provider that several cameras share (surround
  // view) memoises it.
  virtual std::shared_ptr<const std::vector<Eigen::Vector3d>> StaticInWorld(
      size_t index) const;
  static constexpr double kEgoReturnRadiusM = 2.5;
  static constexpr double kBoxMarginM = 0.3;

  // Sweeps with lo_us <= timestamp <= hi_us, in time order.
  std::vector<size_t> SweepsBetween(int64_t lo_us, int64_t hi_us) const;
  // The sweep nearest to t_us (on a tie the later one); nullopt when there is
  // none.
  std::optional<size_t> Nearest(int64_t t_us) const;
};

// One camera of a surround-view clip: its frames, matched one to one with the
// clip's reference frames (DriveClip::frames), each with its own timestamp,
// ego pose (the ego at that camera's capture time, never the LiDAR's),
// mounting and intrinsics.
struct CameraStream {
  // Camera channel, e.g. "CAM_FRONT_LEFT".
  std::string channel;
  std::vector<DriveFrame> frames;
};

struct DriveClip {
  // Clip id, unique in its dataset (e.g. "scene-0916_0006").
  std::string id;
  // Dataset kind and where it was read from (e.g. "nuscenes v1.0-mini at
  // /data/nuscenes").
  std::string dataset;
  // Scene name and the dataset's scene id (nuScenes: the scene token).
  std::string scene_name;
  std::string scene_id;
  // Camera channel of the frames (e.g. "CAM_FRONT").
  std::string channel;
  // Which frames make the clip.
  ClipFrameSource frame_source = ClipFrameSource::kAll;
  // Units of poses, boxes and LiDAR ("metres" for every driving dataset).
  std::string units = "metres";
  std::vector<DriveFrame> frames;
  // Surround view: every camera the user selected, the reference camera
  // (`channel`, `frames`) first; empty for a single-camera clip.
  std::vector<CameraStream> rig;
  // LiDAR of the scene; null when the dataset has none.
  std::shared_ptr<const LidarProvider> lidar;
  // Where each piece came from, e.g. {"poses": "ego_pose.json ∘
  // calibrated_sensor.json", "boxes": "sample_annotation.json (interpolated
  // between keyframes)"}.
  std::map<std::string, std::string> provenance;

  int num_frames() const { return static_cast<int>(frames.size()); }
  // Cameras of the clip: rig.size(), or 1 for a single-camera clip.
  int num_views() const {
    return rig.empty() ? 1 : static_cast<int>(rig.size());
  }
  // The single-camera clip of view `k` (< num_views()): the same id, scene,
  // boxes' instances and LiDAR, with that camera's channel and frames.
  DriveClip View(int k) const;
  // Median time between consecutive frames (s); 0 for fewer than 2 frames.
  double FrameIntervalSeconds() const;
};

}  // namespace geodrive
