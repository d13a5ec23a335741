#pragma once
// Waymo v1 range images (WaymoLaser's compressed bytes) decoded, and their
// returns turned into points in the vehicle frame. The conventions, from
// waymo-open-dataset 99a4cb3 (src/waymo_open_dataset/):
//  - a range image is zlib of a serialized MatrixFloat of shape [H, W, 4]:
//    range, intensity, elongation, no-label-zone (utils/frame_utils.py:56-87);
//    a pixel is a return where range > 0;
//  - row inclinations: the calibration's beam_inclinations, or uniform
//    min + (i + 0.5) / H * (max - min), then reversed, so that row 0 is the
//    highest beam (frame_utils.py:145-152, range_image_utils.py:713-717);
//  - column azimuths: (2 (W - c - 0.5) / W - 1) pi - atan2(E[1,0], E[0,0])
//    for the laser extrinsic E: column 0 at +pi, clockwise; with the
//    extrinsic's yaw added back, column 0 looks back, W/4 left, W/2 ahead,
//    3W/4 right in the vehicle frame (range_image_utils.py:286-291);
//  - a point: (cos az cos inc, sin az cos inc, sin inc) * range in the laser
//    frame, then vehicle = E * p (range_image_utils.py:345-359).
//  - TOP's rolling shutter: range_image_top_pose [H, W, 6] = roll, pitch,
//    yaw, x, y, z is the vehicle -> world pose at each pixel, rotation
//    Rz(yaw) Ry(pitch) Rx(roll) (utils/transform_utils.py:77-126); a point
//    goes world = pixel pose * p, then vehicle = inv(frame pose) * world
//    (frame_utils.py:63-68, 131-162; range_image_utils.py:360-381). Return 2
//    reuses return 1's pixel poses.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "dataset/waymo/waymo_frame.h"

namespace geodrive {

// A decoded MatrixFloat [height, width, channels], row-major.
struct WaymoRangeImage {
  int height = 0;
  int width = 0;
  int channels = 0;
  std::vector<float> values;

  float at(int row, int col, int channel) const {
    return values[(static_cast<size_t>(row) * width + col) * channels +
                  channel];
  }
};

// Inflates and parses one compressed MatrixFloat whose last dimension must be
// `channels` (4 for a return, 6 for TOP's pixel poses). `file`, `record` and
// `what` (e.g. "laser TOP return 1") are named in every error: bad zlib, an
// inflated size over SizeLimits::kMaxMemberBytes or 1100 times the
// compressed bytes, a message protobuf cannot parse or with unknown fields, a
// shape that is not [H, W, channels] or disagrees with the data.
WaymoRangeImage DecodeWaymoRangeImage(const std::string& compressed,
                                      int channels,
                                      const std::string& file,
                                      int64_t record,
                                      const std::string& what);

// The inclination (radians) of each of `height` rows, row 0 the highest.
std::vector<double> WaymoRowInclinations(const WaymoLaserCalibration& laser,
                                         int height);
// The azimuth (radians, laser frame) of each of `width` columns.
std::vector<double> WaymoColumnAzimuths(const WaymoLaserCalibration& laser,
                                        int width);

// The vehicle -> world pose of TOP's pixel (row, col) from its pose image
// (6 channels: roll, pitch, yaw, x, y, z).
Eigen::Matrix4d WaymoPixelPose(const WaymoRangeImage& top_pose,
                               int row,
                               int col);

// The returns (range > 0) of `image` as points in the vehicle frame (at the
// frame pose), row by row. `image` must have 4 channels and, with
// beam_inclinations, as many rows as the calibration has inclinations. With
// `top_pose` (TOP's pose image, the same height and width) and
// `world_from_vehicle` (the frame pose), each point is moved by its pixel's
// pose: vehicle = inv(world_from_vehicle) * pixel_pose * p.
std::vector<Eigen::Vector3d> WaymoRangeImagePoints(
    const WaymoRangeImage& image,
    const WaymoLaserCalibration& laser,
    const WaymoRangeImage* top_pose = nullptr,
    const Eigen::Matrix4d& world_from_vehicle = Eigen::Matrix4d::Identity());

}  // namespace geodrive
