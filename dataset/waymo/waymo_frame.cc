#include "dataset/waymo/waymo_frame.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>
#include <google/protobuf/unknown_field_set.h>

#include <Eigen/Geometry>
#include <climits>
#include <cmath>
#include <set>

#include "dataset/waymo/tfrecord.h"
#include "geometry/util/size_limits.h"
#include "geometry/util/status.h"
#include "waymo_open_dataset/dataset.pb.h"

namespace geodrive {

namespace wod = ::waymo::open_dataset;

namespace {

// Where a frame came from, for the errors.
struct FrameContext {
  const std::string& file;
  int64_t record;
};

template <typename... Args>
[[noreturn]] void Fail(const FrameContext& ctx, const Args&... args) {
  ThrowInputError(ctx.file, "record ", ctx.record, ": ", args...);
}

// The first field anywhere in `message` that the vendored protos do not
// declare (kept by protobuf in the unknown field set): false when none.
bool FindUnknownField(const google::protobuf::Message& message,
                      std::string* where,
                      int* number) {
  const google::protobuf::Reflection* reflection = message.GetReflection();
  const google::protobuf::UnknownFieldSet& unknown =
      reflection->GetUnknownFields(message);
  if (!unknown.empty()) {
    *where = message.GetDescriptor()->full_name();
    *number = unknown.field(0).number();
    return true;
  }
  std::vector<const google::protobuf::FieldDescriptor*> fields;
  reflection->ListFields(message, &fields);
  for (const google::protobuf::FieldDescriptor* field : fields) {
    if (field->cpp_type() !=
        google::protobuf::FieldDescriptor::CPPTYPE_MESSAGE) {
      continue;
    }
    if (field->is_repeated()) {
      const int n = reflection->FieldSize(message, field);
      for (int i = 0; i < n; ++i) {
        if (FindUnknownField(reflection->GetRepeatedMessage(message, field, i),
                             where, number)) {
          return true;
        }
      }
    } else if (FindUnknownField(reflection->GetMessage(message, field), where,
                                number)) {
      return true;
    }
  }
  return false;
}

// A `Transform` (16 doubles, row-major) checked: finite, last row 0 0 0 1,
// a rotation (orthonormal within 1e-5, determinant +1).
Eigen::Matrix4d ReadTransform(const wod::Transform& t,
                              const FrameContext& ctx,
                              const std::string& what) {
  if (t.transform_size() != 16) {
    Fail(ctx, what, " has ", t.transform_size(),
         " values (expected 16, a row-major 4x4)");
  }
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = t.transform(4 * r + c);
  if (!m.allFinite()) Fail(ctx, what, " has a non-finite value");
  const Eigen::RowVector4d last(0, 0, 0, 1);
  if ((m.row(3) - last).cwiseAbs().maxCoeff() > 1e-9)
    Fail(ctx, what, " has a last row other than 0 0 0 1");
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  const double orthogonality =
      (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (orthogonality > 1e-5 || R.determinant() < 0) {
    Fail(ctx, what, " is not a rigid transform (|R^T R - I| = ", orthogonality,
         ", det ", R.determinant(), ")");
  }
  return m;
}

WaymoIntrinsics ReadIntrinsics(const wod::CameraCalibration& c,
                               const FrameContext& ctx,
                               const std::string& what) {
  if (c.intrinsic_size() != 9) {
    Fail(ctx, what, " has ", c.intrinsic_size(),
         " intrinsic values (expected 9: f_u f_v c_u c_v k1 k2 p1 p2 k3)");
  }
  WaymoIntrinsics k;
  double* v[9] = {&k.f_u, &k.f_v, &k.c_u, &k.c_v, &k.k1,
                  &k.k2,  &k.p1,  &k.p2,  &k.k3};
  for (int i = 0; i < 9; ++i) {
    *v[i] = c.intrinsic(i);
    if (!std::isfinite(*v[i])) Fail(ctx, what, " has a non-finite intrinsic");
  }
  if (!(k.f_u > 0) || !(k.f_v > 0))
    Fail(ctx, what, " has focal lengths f_u ", k.f_u, ", f_v ", k.f_v);
  return k;
}

WaymoCameraCalibration ReadCameraCalibration(const wod::CameraCalibration& c,
                                             const FrameContext& ctx) {
  WaymoCameraCalibration out;
  out.name = static_cast<WaymoCameraName>(c.name());
  const std::string what = "camera calibration " + ToString(out.name);
  if (out.name == WaymoCameraName::kUnknown) Fail(ctx, what, " has no name");
  out.intrinsics = ReadIntrinsics(c, ctx, what);
  out.width = c.width();
  out.height = c.height();
  if (out.width <= 0 || out.height <= 0 ||
      out.width > SizeLimits::kMaxImageSide ||
      out.height > SizeLimits::kMaxImageSide) {
    Fail(ctx, what, " has image size ", out.width, "x", out.height,
         " (expected 1..", SizeLimits::kMaxImageSide, " a side)");
  }
  if (!c.has_extrinsic()) Fail(ctx, what, " has no extrinsic");
  out.vehicle_from_camera = VehicleFromOpenCvCamera(
      ReadTransform(c.extrinsic(), ctx, what + " extrinsic"));
  out.rolling_shutter =
      static_cast<WaymoRollingShutter>(c.rolling_shutter_direction());
  return out;
}

WaymoCameraImage ReadCameraImage(const wod::CameraImage& image,
                                 const FrameContext& ctx) {
  WaymoCameraImage out;
  out.name = static_cast<WaymoCameraName>(image.name());
  const std::string what = "camera image " + ToString(out.name);
  if (out.name == WaymoCameraName::kUnknown) Fail(ctx, what, " has no name");
  if (image.image().empty()) Fail(ctx, what, " holds no image bytes");
  out.jpeg = image.image();
  out.has_pose = image.has_pose();
  if (out.has_pose)
    out.world_from_vehicle = ReadTransform(image.pose(), ctx, what + " pose");
  out.has_velocity = image.has_velocity();
  if (out.has_velocity) {
    const wod::Velocity& v = image.velocity();
    out.linear_velocity = Eigen::Vector3d(v.v_x(), v.v_y(), v.v_z());
    out.angular_velocity = Eigen::Vector3d(v.w_x(), v.w_y(), v.w_z());
  }
  out.pose_timestamp = image.pose_timestamp();
  out.shutter = image.shutter();
  out.camera_trigger_time = image.camera_trigger_time();
  out.camera_readout_done_time = image.camera_readout_done_time();
  return out;
}

WaymoBox3d ReadBox3d(const wod::Label& label) {
  WaymoBox3d out;
  out.id = label.id();
  out.type = static_cast<WaymoObjectType>(label.type());
  const wod::Label::Box& b = label.box();
  out.center = Eigen::Vector3d(b.center_x(), b.center_y(), b.center_z());
  out.length = b.length();
  out.width = b.width();
  out.height = b.height();
  out.heading = b.heading();
  return out;
}

WaymoCameraLabels ReadCameraLabels(const wod::CameraLabels& labels) {
  WaymoCameraLabels out;
  out.name = static_cast<WaymoCameraName>(labels.name());
  out.boxes.reserve(labels.labels_size());
  for (const wod::Label& label : labels.labels()) {
    WaymoBox2d box;
    box.id = label.id();
    box.type = static_cast<WaymoObjectType>(label.type());
    box.center_x = label.box().center_x();
    box.center_y = label.box().center_y();
    box.size_x = label.box().length();
    box.size_y = label.box().width();
    out.boxes.push_back(std::move(box));
  }
  return out;
}

WaymoLaserCalibration ReadLaserCalibration(const wod::LaserCalibration& c,
                                           const FrameContext& ctx) {
  WaymoLaserCalibration out;
  out.name = static_cast<WaymoLaserName>(c.name());
  const std::string what = "laser calibration " + ToString(out.name);
  out.beam_inclinations.assign(c.beam_inclinations().begin(),
                               c.beam_inclinations().end());
  out.beam_inclination_min = c.beam_inclination_min();
  out.beam_inclination_max = c.beam_inclination_max();
  if (c.has_extrinsic())
    out.vehicle_from_laser =
        ReadTransform(c.extrinsic(), ctx, what + " extrinsic");
  return out;
}

bool HasRangeImage(const wod::RangeImage& ri) {
  return !ri.range_image_compressed().empty();
}

// The checks across a frame's parts: one image per camera, each with a
// calibration.
void CheckCameras(const WaymoFrame& frame, const FrameContext& ctx) {
  if (frame.images.empty()) {
    Fail(ctx, "frame ", frame.timestamp_micros,
         " has no camera image (a Waymo frame holds up to five)");
  }
  std::set<WaymoCameraName> seen;
  for (const WaymoCameraImage& image : frame.images) {
    if (!seen.insert(image.name).second)
      Fail(ctx, "two camera images named ", ToString(image.name));
    if (frame.Calibration(image.name) == nullptr) {
      Fail(ctx, "camera image ", ToString(image.name),
           " has no calibration in the frame's context");
    }
  }
}

}  // namespace

std::string ToString(WaymoCameraName name) {
  static const char* const kNames[] = {
      "UNKNOWN",    "FRONT",     "FRONT_LEFT", "FRONT_RIGHT", "SIDE_LEFT",
      "SIDE_RIGHT", "REAR_LEFT", "REAR",       "REAR_RIGHT"};
  const int i = static_cast<int>(name);
  return i >= 0 && i < 9 ? kNames[i] : "camera " + std::to_string(i);
}

std::string ToString(WaymoLaserName name) {
  static const char* const kNames[] = {"UNKNOWN",   "TOP",        "FRONT",
                                       "SIDE_LEFT", "SIDE_RIGHT", "REAR"};
  const int i = static_cast<int>(name);
  return i >= 0 && i < 6 ? kNames[i] : "laser " + std::to_string(i);
}

std::string ToString(WaymoRollingShutter direction) {
  static const char* const kNames[] = {"UNKNOWN",       "TOP_TO_BOTTOM",
                                       "LEFT_TO_RIGHT", "BOTTOM_TO_TOP",
                                       "RIGHT_TO_LEFT", "GLOBAL_SHUTTER"};
  const int i = static_cast<int>(direction);
  return i >= 0 && i < 6 ? kNames[i] : "direction " + std::to_string(i);
}

std::string ToString(WaymoObjectType type) {
  static const char* const kNames[] = {"TYPE_UNKNOWN", "TYPE_VEHICLE",
                                       "TYPE_PEDESTRIAN", "TYPE_SIGN",
                                       "TYPE_CYCLIST"};
  const int i = static_cast<int>(type);
  return i >= 0 && i < 5 ? kNames[i] : "type " + std::to_string(i);
}

WaymoProjection ProjectWaymoCamera(const WaymoCameraCalibration& camera,
                                   const Eigen::Vector3d& point,
                                   Eigen::Vector2d* pixel) {
  // The radial factor's trusted range (camera_model.cc, kMinRadialDistortion
  // and kMaxRadialDistortion).
  constexpr double kMinRadialFactor = 0.8;
  constexpr double kMaxRadialFactor = 1.2;
  if (!(point.z() > 0)) return WaymoProjection::kBehind;
  const WaymoIntrinsics& k = camera.intrinsics;
  const double u = point.x() / point.z();
  const double v = point.y() / point.z();
  const double r2 = u * u + v * v;
  const double radial = 1 + r2 * (k.k1 + r2 * (k.k2 + r2 * k.k3));
  if (radial < kMinRadialFactor || radial > kMaxRadialFactor) {
    const double reach =
        std::hypot(camera.width, camera.height) / std::sqrt(r2);
    *pixel = Eigen::Vector2d(u * reach + k.c_u, v * reach + k.c_v);
    return WaymoProjection::kDistortionOutOfRange;
  }
  const double ud = u * radial + 2 * k.p1 * u * v + k.p2 * (r2 + 2 * u * u);
  const double vd = v * radial + k.p1 * (r2 + 2 * v * v) + 2 * k.p2 * u * v;
  *pixel = Eigen::Vector2d(k.f_u * ud + k.c_u, k.f_v * vd + k.c_v);
  return WaymoProjection::kValid;
}

Eigen::Matrix4d WaymoCameraFromOpenCvCamera() {
  // Columns: the OpenCV axes in Waymo camera coordinates. OpenCV x (right)
  // is Waymo -y (y points left), OpenCV y (down) is Waymo -z (z points up),
  // OpenCV z (forward) is Waymo +x.
  Eigen::Matrix4d waymo_camera_from_opencv = Eigen::Matrix4d::Zero();
  waymo_camera_from_opencv(1, 0) = -1;
  waymo_camera_from_opencv(2, 1) = -1;
  waymo_camera_from_opencv(0, 2) = 1;
  waymo_camera_from_opencv(3, 3) = 1;
  return waymo_camera_from_opencv;
}

Eigen::Matrix4d VehicleFromOpenCvCamera(
    const Eigen::Matrix4d& vehicle_from_waymo_camera) {
  return vehicle_from_waymo_camera * WaymoCameraFromOpenCvCamera();
}

Eigen::Matrix4d VehicleFromWaymoCamera(
    const Eigen::Matrix4d& vehicle_from_opencv_camera) {
  // The inverse of the permutation is its transpose (exact in doubles).
  return vehicle_from_opencv_camera *
         WaymoCameraFromOpenCvCamera().transpose();
}

std::vector<Eigen::Vector3d> WaymoBoxCorners(const WaymoBox3d& box) {
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(box.heading, Eigen::Vector3d::UnitZ())
          .toRotationMatrix();
  std::vector<Eigen::Vector3d> corners;
  corners.reserve(8);
  for (int sx : {-1, 1})
    for (int sy : {-1, 1})
      for (int sz : {-1, 1}) {
        const Eigen::Vector3d local(0.5 * sx * box.length, 0.5 * sy * box.width,
                                    0.5 * sz * box.height);
        corners.push_back(box.center + R * local);
      }
  return corners;
}

const WaymoCameraCalibration* WaymoFrame::Calibration(
    WaymoCameraName name) const {
  for (const WaymoCameraCalibration& c : camera_calibrations)
    if (c.name == name) return &c;
  return nullptr;
}

const WaymoCameraImage* WaymoFrame::Image(WaymoCameraName name) const {
  for (const WaymoCameraImage& image : images)
    if (image.name == name) return &image;
  return nullptr;
}

const WaymoCameraLabels* WaymoFrame::ProjectedLidarLabels(
    WaymoCameraName name) const {
  for (const WaymoCameraLabels& labels : projected_lidar_labels)
    if (labels.name == name) return &labels;
  return nullptr;
}

WaymoFrame ParseWaymoFrame(std::string_view bytes,
                           const std::string& file,
                           int64_t record_index) {
  const FrameContext ctx{file, record_index};
  if (bytes.size() > static_cast<size_t>(INT_MAX))
    Fail(ctx, "a Frame of ", bytes.size(), " bytes (protobuf reads < 2 GiB)");
  wod::Frame proto;
  if (!proto.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
    Fail(ctx, "not a waymo.open_dataset.Frame message (", bytes.size(),
         " bytes that protobuf cannot parse)");
  }
  std::string where;
  int number = 0;
  if (FindUnknownField(proto, &where, &number)) {
    Fail(ctx, "unknown field number ", number, " in ", where,
         " (not in the vendored dataset.proto of waymo-open-dataset 99a4cb3)");
  }
  WaymoFrame frame;
  frame.context_name = proto.context().name();
  frame.timestamp_micros = proto.timestamp_micros();
  if (!proto.has_pose()) Fail(ctx, "frame has no pose");
  frame.world_from_vehicle = ReadTransform(proto.pose(), ctx, "frame pose");
  for (const wod::CameraCalibration& c : proto.context().camera_calibrations())
    frame.camera_calibrations.push_back(ReadCameraCalibration(c, ctx));
  for (const wod::LaserCalibration& c : proto.context().laser_calibrations())
    frame.laser_calibrations.push_back(ReadLaserCalibration(c, ctx));
  for (const wod::CameraImage& image : proto.images())
    frame.images.push_back(ReadCameraImage(image, ctx));
  for (const wod::Label& label : proto.laser_labels())
    frame.laser_labels.push_back(ReadBox3d(label));
  for (const wod::CameraLabels& labels : proto.projected_lidar_labels())
    frame.projected_lidar_labels.push_back(ReadCameraLabels(labels));
  for (const wod::CameraLabels& labels : proto.camera_labels())
    frame.camera_labels.push_back(ReadCameraLabels(labels));
  frame.num_lasers = proto.lasers_size();
  for (const wod::Laser& laser : proto.lasers()) {
    if (HasRangeImage(laser.ri_return1()) || HasRangeImage(laser.ri_return2()))
      frame.has_range_images = true;
    WaymoLaser out;
    out.name = static_cast<WaymoLaserName>(laser.name());
    out.return1 = laser.ri_return1().range_image_compressed();
    out.return2 = laser.ri_return2().range_image_compressed();
    out.top_pose = laser.ri_return1().range_image_pose_compressed();
    frame.lasers.push_back(std::move(out));
  }
  CheckCameras(frame, ctx);
  return frame;
}

std::vector<WaymoFrame> ReadWaymoFrames(const std::string& path) {
  TfRecordReader reader(path);
  std::vector<WaymoFrame> frames;
  std::string data;
  while (true) {
    const int64_t index = reader.index();
    if (!reader.Next(&data)) break;
    frames.push_back(ParseWaymoFrame(data, path, index));
  }
  return frames;
}

}  // namespace geodrive
