#pragma once
// One Waymo Open Dataset v1 `Frame` (waymo_open_dataset/dataset.proto, vendored
// in third_party/waymo_open_dataset/) as plain structs: no protobuf type
// leaves dataset/waymo/*.cc.
//
// Conventions, converted on reading:
//  - Poses are 4x4 row-major `Transform`s in metres, named by frame
//    (docs/reference/conventions.md): `world_from_vehicle` is the frame pose
//    (vehicle -> world), `vehicle_from_camera` a camera's extrinsic.
//  - Camera axes: Waymo's camera frame is x forward, y left, z up
//    (wdl_limited/camera/camera_model.cc:576-646); ours is OpenCV, x right,
//    y down, z forward. The one conversion is VehicleFromOpenCvCamera().
//  - Intrinsics are Waymo's f_u f_v c_u c_v k1 k2 p1 p2 k3 at the image's
//    full size; ProjectWaymoCamera applies their OpenCV-style distortion.
//  - Boxes (`laser_labels`) are in the vehicle frame: centre, length (along
//    the heading), width, height, heading (yaw about +z, radians).
//
// What is absent is reported, not fatal: a frame without range images (the
// shared real frame has five empty `Laser` messages), without labels, without
// camera poses. A frame without any camera image, a field this reader does not
// know (an unknown field number anywhere in the message) and malformed
// calibrations are InputErrors naming the file and the record index.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace geodrive {

// CameraName.Name (v1 segments have the first five).
enum class WaymoCameraName {
  kUnknown = 0,
  kFront = 1,
  kFrontLeft = 2,
  kFrontRight = 3,
  kSideLeft = 4,
  kSideRight = 5,
  kRearLeft = 6,
  kRear = 7,
  kRearRight = 8,
};
// "FRONT", "FRONT_LEFT", ... as the proto spells them.
std::string ToString(WaymoCameraName name);

// LaserName.Name.
enum class WaymoLaserName {
  kUnknown = 0,
  kTop = 1,
  kFront = 2,
  kSideLeft = 3,
  kSideRight = 4,
  kRear = 5,
};
std::string ToString(WaymoLaserName name);

// CameraCalibration.RollingShutterReadOutDirection.
enum class WaymoRollingShutter {
  kUnknown = 0,
  kTopToBottom = 1,
  kLeftToRight = 2,
  kBottomToTop = 3,
  kRightToLeft = 4,
  kGlobalShutter = 5,
};
std::string ToString(WaymoRollingShutter direction);

// Label.Type.
enum class WaymoObjectType {
  kUnknown = 0,
  kVehicle = 1,
  kPedestrian = 2,
  kSign = 3,
  kCyclist = 4,
};
std::string ToString(WaymoObjectType type);

// CameraCalibration.intrinsic, in pixels of the full image.
struct WaymoIntrinsics {
  double f_u = 0, f_v = 0, c_u = 0, c_v = 0;
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;
};

// The extrinsic of a Waymo camera (camera x forward, y left, z up ->
// vehicle) as vehicle_from_camera with OpenCV camera axes (x right, y down,
// z forward): vehicle_from_waymo_camera * waymo_camera_from_opencv, where
// waymo_camera_from_opencv maps OpenCV x to Waymo -y, y to -z and z to +x.
Eigen::Matrix4d VehicleFromOpenCvCamera(
    const Eigen::Matrix4d& vehicle_from_waymo_camera);
// The inverse, for writers: vehicle_from_waymo_camera from the OpenCV-axes
// extrinsic. Both directions use the one permutation
// WaymoCameraFromOpenCvCamera().
Eigen::Matrix4d VehicleFromWaymoCamera(
    const Eigen::Matrix4d& vehicle_from_opencv_camera);
// The axis permutation itself (OpenCV camera -> Waymo camera).
Eigen::Matrix4d WaymoCameraFromOpenCvCamera();

struct WaymoCameraCalibration {
  WaymoCameraName name = WaymoCameraName::kUnknown;
  WaymoIntrinsics intrinsics;
  int width = 0;
  int height = 0;
  // Camera (OpenCV axes) -> vehicle.
  Eigen::Matrix4d vehicle_from_camera = Eigen::Matrix4d::Identity();
  WaymoRollingShutter rolling_shutter = WaymoRollingShutter::kUnknown;
};

// How a point projected (ProjectWaymoCamera).
enum class WaymoProjection {
  // In front of the camera, within the trusted range of the distortion.
  kValid,
  // In front, but where the radial factor leaves [0.8, 1.2]: the pixel is a
  // placeholder outside the image, in the point's direction.
  kDistortionOutOfRange,
  // Not in front of the camera (z <= 0): no pixel.
  kBehind,
};

// Projects `point` (OpenCV camera axes, metres) with Waymo's camera model
// (camera_model.cc DirectionToImage, the global-shutter path): pinhole on
// x/z, y/z, radial factor 1 + k1 r^2 + k2 r^4 + k3 r^6 and OpenCV's
// tangential terms (p1, p2), then f and c. Where the radial factor leaves
// [0.8, 1.2] the polynomial is not trusted (it folds back at wide angles):
// as Waymo's model does, the pixel is then put at hypot(width, height) from
// (c_u, c_v) along the point's direction, and kDistortionOutOfRange returned.
WaymoProjection ProjectWaymoCamera(const WaymoCameraCalibration& camera,
                                   const Eigen::Vector3d& point,
                                   Eigen::Vector2d* pixel);

struct WaymoCameraImage {
  WaymoCameraName name = WaymoCameraName::kUnknown;
  // The encoded image as stored (JPEG).
  std::string jpeg;
  // CameraImage.pose: the vehicle pose (vehicle -> world) at the image's
  // timestamp, when stored.
  bool has_pose = false;
  Eigen::Matrix4d world_from_vehicle = Eigen::Matrix4d::Identity();
  // CameraImage.velocity: the vehicle's linear (m/s) and angular (rad/s)
  // velocity in the world frame, when stored.
  bool has_velocity = false;
  Eigen::Vector3d linear_velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();
  // Seconds: the pose's timestamp, the shutter duration, the trigger and the
  // end of the readout (0 when absent).
  double pose_timestamp = 0;
  double shutter = 0;
  double camera_trigger_time = 0;
  double camera_readout_done_time = 0;
};

// A `laser_labels` box, in the vehicle frame.
struct WaymoBox3d {
  // Stable across the frames of a segment.
  std::string id;
  WaymoObjectType type = WaymoObjectType::kUnknown;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  // Extents in metres: along the heading, across it, vertical.
  double length = 0, width = 0, height = 0;
  // Yaw about the vehicle's +z, radians (0: along +x).
  double heading = 0;
};

// The 8 corners of `box` in the vehicle frame.
std::vector<Eigen::Vector3d> WaymoBoxCorners(const WaymoBox3d& box);

// A 2D box of `camera_labels` / `projected_lidar_labels`, in pixels.
struct WaymoBox2d {
  // For projected_lidar_labels: "<laser label id>_<CAMERA NAME>".
  std::string id;
  WaymoObjectType type = WaymoObjectType::kUnknown;
  double center_x = 0, center_y = 0;
  // Extent along x (columns) and along y (rows).
  double size_x = 0, size_y = 0;
};

// The 2D boxes of one camera.
struct WaymoCameraLabels {
  WaymoCameraName name = WaymoCameraName::kUnknown;
  std::vector<WaymoBox2d> boxes;
};

struct WaymoLaserCalibration {
  WaymoLaserName name = WaymoLaserName::kUnknown;
  // Per-row inclinations in radians when stored (TOP), else empty and the
  // rows are uniform between min and max.
  std::vector<double> beam_inclinations;
  double beam_inclination_min = 0, beam_inclination_max = 0;
  // Laser -> vehicle.
  Eigen::Matrix4d vehicle_from_laser = Eigen::Matrix4d::Identity();
};

// One `Laser` message: its range images as stored (decoded by
// dataset/waymo/waymo_range_image.h).
struct WaymoLaser {
  WaymoLaserName name = WaymoLaserName::kUnknown;
  // RangeImage.range_image_compressed of the first and second return: zlib
  // of a serialized MatrixFloat [H, W, 4]; empty when absent.
  std::string return1;
  std::string return2;
  // TOP's ri_return1.range_image_pose_compressed: zlib of a MatrixFloat
  // [H, W, 6], the vehicle pose at each pixel (rolling shutter); empty when
  // absent.
  std::string top_pose;
};

struct WaymoFrame {
  // Context.name: the segment.
  std::string context_name;
  int64_t timestamp_micros = 0;
  // The frame pose: vehicle -> world.
  Eigen::Matrix4d world_from_vehicle = Eigen::Matrix4d::Identity();
  std::vector<WaymoCameraCalibration> camera_calibrations;
  std::vector<WaymoCameraImage> images;
  std::vector<WaymoBox3d> laser_labels;
  std::vector<WaymoCameraLabels> projected_lidar_labels;
  std::vector<WaymoCameraLabels> camera_labels;
  std::vector<WaymoLaserCalibration> laser_calibrations;
  // The `Laser` messages, their count and whether any holds a range image
  // (return 1 or 2).
  std::vector<WaymoLaser> lasers;
  int num_lasers = 0;
  bool has_range_images = false;

  // The calibration / image / labels of `name`, or nullptr.
  const WaymoCameraCalibration* Calibration(WaymoCameraName name) const;
  const WaymoCameraImage* Image(WaymoCameraName name) const;
  const WaymoCameraLabels* ProjectedLidarLabels(WaymoCameraName name) const;
};

// Parses one serialized `Frame` (a TFRecord record's data). `file` and
// `record_index` are named in every error:
// "<file>: record <i>: <what>".
WaymoFrame ParseWaymoFrame(std::string_view bytes,
                           const std::string& file,
                           int64_t record_index);

// Every frame of a TFRecord file.
std::vector<WaymoFrame> ReadWaymoFrames(const std::string& path);

}  // namespace geodrive
