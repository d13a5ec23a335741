#pragma once
// Writes the synthetic world (dataset/synthetic/synthetic_world.h) as Waymo
// Open Dataset v1 segments: one TFRecord file of `Frame` protos per scene,
// `<out>/segment-<context>_with_camera_labels.tfrecord`, read back by
// dataset/waymo/waymo_frame.h. Per frame (10 Hz): the frame pose, five
// cameras (FRONT, FRONT_LEFT, FRONT_RIGHT, SIDE_LEFT, SIDE_RIGHT; JPEG,
// pinhole, zero distortion, global shutter) rendered at their own trigger
// times with their own poses, laser_labels (the vehicles within 75 m, ids
// stable across frames), projected_lidar_labels and camera_labels (the
// vehicles' visible pixels), and the TOP LiDAR's first return as a range image
// with its pixel-pose image. Layout and conventions: docs/SYNTHETIC.md.
// Same options -> byte-identical files.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "dataset/synthetic/synthetic_world.h"
#include "dataset/waymo/waymo_frame.h"
#include "geometry/camera.h"
#include "geometry/rigid3.h"

namespace geodrive {

struct SyntheticWaymoOptions {
  // Number of scenes (one segment file each) and the world seed.
  int num_scenes = 1;
  uint64_t seed = 7;
  // FRONT, FRONT_LEFT and FRONT_RIGHT image size (Waymo: 1920x1280); SIDE_*
  // keep this width and 886/1280 of the height. Focal lengths scale with it.
  int image_width = 1920, image_height = 1280;
  // Segment length in seconds: floor(10 * duration) frames at 10 Hz.
  double scene_duration_s = 20.0;
  // The brake-and-stop scenes reverse a few metres after the stop.
  bool reverse_after_stop = true;
  // TOP range image: 64 rows x this many columns (Waymo: 2650).
  int lidar_columns = 2650;
  // JPEG quality of the camera images.
  int jpeg_quality = 90;
  // Optional progress sink (one line per call).
  std::function<void(const std::string&)> progress;

  // Empty if valid, else the reason (one line).
  std::string Validate() const;
  bool Check() const { return Validate().empty(); }
};

struct SyntheticWaymoSummary {
  std::vector<std::string> files;
  int64_t num_frames = 0, num_images = 0, num_laser_labels = 0;
  int64_t num_lidar_returns = 0, num_bytes = 0;
  double seconds = 0;

  std::string BriefReport() const;
};

// Writes one segment file per scene into out_dir (created if needed; existing
// files are overwritten). Throws InputError on invalid options or unwritable
// paths.
SyntheticWaymoSummary WriteSyntheticWaymo(const SyntheticWaymoOptions& options,
                                          const std::string& out_dir);

// ---- The rig and timeline (what the frames say, for tests and tools) ----

constexpr int kSyntheticWaymoFrameRateHz = 10;

// One camera of the rig.
struct SyntheticWaymoCamera {
  WaymoCameraName name = WaymoCameraName::kUnknown;
  // Pinhole intrinsics (kIntegerIndex: Waymo's c_u, c_v are cx, cy).
  PinholeCamera camera;
  // Camera (OpenCV axes: x right, y down, z forward) -> vehicle.
  Rigid3d ego_from_camera;
  // Trigger time after the frame time, seconds.
  double time_offset_s = 0;
};
// The five cameras at the options' image size, in CameraName order.
std::vector<SyntheticWaymoCamera> SyntheticWaymoRig(
    const SyntheticWaymoOptions& options);
// TOP: vehicle_from_laser (no rotation) and the 64 beam inclinations
// (radians, ascending: beam_inclinations[r] is the ring r of
// SyntheticWorld::CastLidar with SyntheticWaymoLidarOptions).
WaymoLaserCalibration SyntheticWaymoTopCalibration();
LidarOptions SyntheticWaymoLidarOptions(const SyntheticWaymoOptions& options);

// Frames of a scene, the time of frame i (seconds since the scene start) and
// its timestamp_micros.
int SyntheticWaymoNumFrames(const SyntheticWaymoOptions& options);
double SyntheticWaymoFrameSeconds(int frame_index);
int64_t SyntheticWaymoTimestampMicros(const SyntheticWaymoOptions& options,
                                      int scene_index,
                                      int frame_index);
// The world of scene i.
SyntheticWorldOptions SyntheticWaymoWorldOptions(
    const SyntheticWaymoOptions& options, int scene_index);
// Context name ("synthetic_<seed>_<scene>_000_<ms>") and file name
// ("segment-<context>_with_camera_labels.tfrecord") of scene i.
std::string SyntheticWaymoContextName(const SyntheticWaymoOptions& options,
                                      int scene_index);
std::string SyntheticWaymoFileName(const SyntheticWaymoOptions& options,
                                   int scene_index);
// The laser_labels id of vehicle `id`, stable across a segment's frames.
std::string SyntheticWaymoLabelId(int vehicle_id);

}  // namespace geodrive
