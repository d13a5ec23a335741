#include "dataset/waymo/waymo_range_image.h"

#include <zlib.h>

#include <Eigen/Geometry>
#include <climits>
#include <cmath>

#include "geometry/util/size_limits.h"
#include "geometry/util/status.h"
#include "waymo_open_dataset/dataset.pb.h"

namespace geodrive {

namespace wod = ::waymo::open_dataset;

namespace {

// Inflates zlib `in`, refusing output over `limit` bytes or over the
// compression ratio limit before it is produced.
std::string Inflate(const std::string& in,
                    const std::string& where,
                    uint64_t limit) {
  z_stream z{};
  if (inflateInit(&z) != Z_OK) ThrowInputError(where, "zlib cannot start");
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = static_cast<uInt>(in.size());
  std::string out;
  char buffer[1 << 16];
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    z.next_out = reinterpret_cast<Bytef*>(buffer);
    z.avail_out = sizeof(buffer);
    rc = inflate(&z, Z_NO_FLUSH);
    if (rc != Z_OK && rc != Z_STREAM_END) {
      inflateEnd(&z);
      ThrowInputError(where, "not valid zlib data (",
                      rc == Z_BUF_ERROR ? "truncated" : "corrupt", ")");
    }
    const size_t produced = sizeof(buffer) - z.avail_out;
    const uint64_t total = out.size() + produced;
    if (total > limit ||
        (total > SizeLimits::kRatioFreeBytes &&
         total / SizeLimits::kMaxCompressionRatio >= in.size())) {
      inflateEnd(&z);
      ThrowInputError(where, "inflates to more than ", total, " bytes from ",
                      in.size(), " (over the limit of ", limit, " bytes or ",
                      SizeLimits::kMaxCompressionRatio, ":1)");
    }
    out.append(buffer, produced);
  }
  inflateEnd(&z);
  return out;
}

}  // namespace

WaymoRangeImage DecodeWaymoRangeImage(const std::string& compressed,
                                      int channels,
                                      const std::string& file,
                                      int64_t record,
                                      const std::string& what) {
  const std::string where =
      internal::StrCat(file, ": record ", record, ": ", what);
  if (compressed.size() > static_cast<size_t>(UINT_MAX))
    ThrowInputError(where, "compressed range image over 4 GiB");
  const std::string bytes =
      Inflate(compressed, where, SizeLimits::kMaxMemberBytes);
  if (bytes.size() > static_cast<size_t>(INT_MAX))
    ThrowInputError(where, "a MatrixFloat over 2 GiB");
  wod::MatrixFloat matrix;
  if (!matrix.ParseFromArray(bytes.data(), static_cast<int>(bytes.size())))
    ThrowInputError(where, "not a MatrixFloat message");
  if (!matrix.GetReflection()->GetUnknownFields(matrix).empty() ||
      !matrix.shape().GetReflection()->GetUnknownFields(matrix.shape()).empty())
    ThrowInputError(where, "a MatrixFloat with unknown fields");
  const auto& dims = matrix.shape().dims();
  if (dims.size() != 3 || dims[0] <= 0 || dims[1] <= 0 || dims[2] != channels) {
    std::string shape;
    for (int d : dims) shape += (shape.empty() ? "" : ", ") + std::to_string(d);
    ThrowInputError(where, "shape [", shape, "], expected [H, W, ", channels,
                    "]");
  }
  WaymoRangeImage image;
  image.height = dims[0];
  image.width = dims[1];
  image.channels = channels;
  const uint64_t expected = SaturatingMul(
      SaturatingMul(static_cast<uint64_t>(dims[0]), dims[1]), channels);
  if (expected != static_cast<uint64_t>(matrix.data_size())) {
    ThrowInputError(where, "shape [", dims[0], ", ", dims[1], ", ", channels,
                    "] needs ", expected, " values, the data has ",
                    matrix.data_size());
  }
  image.values.assign(matrix.data().begin(), matrix.data().end());
  return image;
}

std::vector<double> WaymoRowInclinations(const WaymoLaserCalibration& laser,
                                         int height) {
  std::vector<double> rows;
  if (!laser.beam_inclinations.empty()) {
    rows = laser.beam_inclinations;
  } else {
    const double lo = laser.beam_inclination_min;
    const double hi = laser.beam_inclination_max;
    for (int i = 0; i < height; ++i)
      rows.push_back(lo + (i + 0.5) / height * (hi - lo));
  }
  // Stored lowest first; row 0 of the image is the highest beam.
  return std::vector<double>(rows.rbegin(), rows.rend());
}

std::vector<double> WaymoColumnAzimuths(const WaymoLaserCalibration& laser,
                                        int width) {
  const Eigen::Matrix4d& E = laser.vehicle_from_laser;
  const double correction = std::atan2(E(1, 0), E(0, 0));
  std::vector<double> columns(width);
  for (int c = 0; c < width; ++c)
    columns[c] = (2.0 * (width - c - 0.5) / width - 1.0) * M_PI - correction;
  return columns;
}

Eigen::Matrix4d WaymoPixelPose(const WaymoRangeImage& top_pose,
                               int row,
                               int col) {
  const double roll = top_pose.at(row, col, 0);
  const double pitch = top_pose.at(row, col, 1);
  const double yaw = top_pose.at(row, col, 2);
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() =
      (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  m.topRightCorner<3, 1>() =
      Eigen::Vector3d(top_pose.at(row, col, 3), top_pose.at(row, col, 4),
                      top_pose.at(row, col, 5));
  return m;
}

std::vector<Eigen::Vector3d> WaymoRangeImagePoints(
    const WaymoRangeImage& image,
    const WaymoLaserCalibration& laser,
    const WaymoRangeImage* top_pose,
    const Eigen::Matrix4d& world_from_vehicle) {
  GEODRIVE_CHECK_INPUT(image.channels == 4, "laser ", ToString(laser.name),
                       ": a range image has 4 channels, this one ",
                       image.channels);
  const std::vector<double> inclinations =
      WaymoRowInclinations(laser, image.height);
  GEODRIVE_CHECK_INPUT(
      static_cast<int>(inclinations.size()) == image.height, "laser ",
      ToString(laser.name), ": ", inclinations.size(),
      " beam inclinations for a range image of ", image.height, " rows");
  if (top_pose != nullptr) {
    GEODRIVE_CHECK_INPUT(
        top_pose->channels == 6 && top_pose->height == image.height &&
            top_pose->width == image.width,
        "laser ", ToString(laser.name), ": a pixel-pose image of ",
        top_pose->height, "x", top_pose->width, "x", top_pose->channels,
        " for a range image of ", image.height, "x", image.width,
        " (expected the same rows and columns, 6 channels)");
  }
  const Eigen::Matrix4d vehicle_from_world = world_from_vehicle.inverse();
  const std::vector<double> azimuths = WaymoColumnAzimuths(laser, image.width);
  const Eigen::Matrix3d R = laser.vehicle_from_laser.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = laser.vehicle_from_laser.topRightCorner<3, 1>();
  std::vector<Eigen::Vector3d> points;
  for (int r = 0; r < image.height; ++r) {
    const double ci = std::cos(inclinations[r]);
    const double si = std::sin(inclinations[r]);
    for (int c = 0; c < image.width; ++c) {
      const double range = image.at(r, c, 0);
      if (!(range > 0)) continue;
      const Eigen::Vector3d p(std::cos(azimuths[c]) * ci * range,
                              std::sin(azimuths[c]) * ci * range, si * range);
      const Eigen::Vector3d vehicle = R * p + t;
      if (top_pose == nullptr) {
        points.push_back(vehicle);
        continue;
      }
      const Eigen::Matrix4d frame_from_pixel =
          vehicle_from_world * WaymoPixelPose(*top_pose, r, c);
      points.push_back((frame_from_pixel * vehicle.homogeneous()).head<3>());
    }
  }
  return points;
}

}  // namespace geodrive
