#include "dataset/waymo/waymo_writer.h"

#include <zlib.h>

#include "geometry/util/status.h"
#include "waymo_open_dataset/dataset.pb.h"

namespace geodrive {

namespace wod = ::waymo::open_dataset;

namespace {

void WriteTransform(const Eigen::Matrix4d& m, wod::Transform* out) {
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out->add_transform(m(r, c));
}

void WriteCounts(
    const std::vector<std::pair<WaymoObjectType, int>>& counts,
    google::protobuf::RepeatedPtrField<wod::Context::Stats::ObjectCount>* out) {
  for (const auto& [type, count] : counts) {
    wod::Context::Stats::ObjectCount* c = out->Add();
    c->set_type(static_cast<wod::Label::Type>(type));
    c->set_count(count);
  }
}

void WriteCameraCalibration(const WaymoCameraCalibration& c,
                            wod::CameraCalibration* out) {
  out->set_name(static_cast<wod::CameraName::Name>(c.name));
  const WaymoIntrinsics& k = c.intrinsics;
  for (double v : {k.f_u, k.f_v, k.c_u, k.c_v, k.k1, k.k2, k.p1, k.p2, k.k3})
    out->add_intrinsic(v);
  WriteTransform(VehicleFromWaymoCamera(c.vehicle_from_camera),
                 out->mutable_extrinsic());
  out->set_width(c.width);
  out->set_height(c.height);
  out->set_rolling_shutter_direction(
      static_cast<wod::CameraCalibration::RollingShutterReadOutDirection>(
          c.rolling_shutter));
}

void WriteLaserCalibration(const WaymoLaserCalibration& c,
                           wod::LaserCalibration* out) {
  out->set_name(static_cast<wod::LaserName::Name>(c.name));
  for (double v : c.beam_inclinations) out->add_beam_inclinations(v);
  out->set_beam_inclination_min(c.beam_inclination_min);
  out->set_beam_inclination_max(c.beam_inclination_max);
  WriteTransform(c.vehicle_from_laser, out->mutable_extrinsic());
}

void WriteCameraImage(const WaymoCameraImage& image, wod::CameraImage* out) {
  out->set_name(static_cast<wod::CameraName::Name>(image.name));
  out->set_image(image.jpeg);
  if (image.has_pose)
    WriteTransform(image.world_from_vehicle, out->mutable_pose());
  if (image.has_velocity) {
    wod::Velocity* v = out->mutable_velocity();
    v->set_v_x(static_cast<float>(image.linear_velocity.x()));
    v->set_v_y(static_cast<float>(image.linear_velocity.y()));
    v->set_v_z(static_cast<float>(image.linear_velocity.z()));
    v->set_w_x(image.angular_velocity.x());
    v->set_w_y(image.angular_velocity.y());
    v->set_w_z(image.angular_velocity.z());
  }
  out->set_pose_timestamp(image.pose_timestamp);
  out->set_shutter(image.shutter);
  out->set_camera_trigger_time(image.camera_trigger_time);
  out->set_camera_readout_done_time(image.camera_readout_done_time);
}

void WriteBox3d(const WaymoBox3d& box, wod::Label* out) {
  out->set_id(box.id);
  out->set_type(static_cast<wod::Label::Type>(box.type));
  wod::Label::Box* b = out->mutable_box();
  b->set_center_x(box.center.x());
  b->set_center_y(box.center.y());
  b->set_center_z(box.center.z());
  b->set_length(box.length);
  b->set_width(box.width);
  b->set_height(box.height);
  b->set_heading(box.heading);
}

void WriteCameraLabels(const WaymoCameraLabels& labels,
                       wod::CameraLabels* out) {
  out->set_name(static_cast<wod::CameraName::Name>(labels.name));
  for (const WaymoBox2d& box : labels.boxes) {
    wod::Label* l = out->add_labels();
    l->set_id(box.id);
    l->set_type(static_cast<wod::Label::Type>(box.type));
    wod::Label::Box* b = l->mutable_box();
    b->set_center_x(box.center_x);
    b->set_center_y(box.center_y);
    b->set_length(box.size_x);
    b->set_width(box.size_y);
  }
}

void WriteLaser(const WaymoLaser& laser, wod::Laser* out) {
  out->set_name(static_cast<wod::LaserName::Name>(laser.name));
  if (!laser.return1.empty() || !laser.top_pose.empty()) {
    wod::RangeImage* r1 = out->mutable_ri_return1();
    if (!laser.return1.empty()) r1->set_range_image_compressed(laser.return1);
    if (!laser.top_pose.empty())
      r1->set_range_image_pose_compressed(laser.top_pose);
  }
  if (!laser.return2.empty())
    out->mutable_ri_return2()->set_range_image_compressed(laser.return2);
}

}  // namespace

std::string CompressWaymoRangeImage(const WaymoRangeImage& image) {
  GEODRIVE_CHECK_INPUT(
      image.height > 0 && image.width > 0 && image.channels > 0 &&
          image.values.size() ==
              static_cast<size_t>(image.height) * image.width * image.channels,
      "CompressWaymoRangeImage: values do not match the shape ", image.height,
      "x", image.width, "x", image.channels);
  wod::MatrixFloat matrix;
  matrix.mutable_data()->Add(image.values.begin(), image.values.end());
  for (int d : {image.height, image.width, image.channels})
    matrix.mutable_shape()->add_dims(d);
  std::string bytes;
  GEODRIVE_CHECK_INPUT(matrix.SerializeToString(&bytes),
                       "CompressWaymoRangeImage: cannot serialize");
  uLongf size = compressBound(bytes.size());
  std::string out(size, '\0');
  const int rc =
      compress2(reinterpret_cast<Bytef*>(out.data()), &size,
                reinterpret_cast<const Bytef*>(bytes.data()), bytes.size(), 6);
  GEODRIVE_CHECK_INPUT(rc == Z_OK, "CompressWaymoRangeImage: zlib error ", rc);
  out.resize(size);
  return out;
}

std::string SerializeWaymoFrame(const WaymoFrame& frame,
                                const WaymoContextStats& stats) {
  wod::Frame out;
  wod::Context* context = out.mutable_context();
  context->set_name(frame.context_name);
  for (const WaymoCameraCalibration& c : frame.camera_calibrations)
    WriteCameraCalibration(c, context->add_camera_calibrations());
  for (const WaymoLaserCalibration& c : frame.laser_calibrations)
    WriteLaserCalibration(c, context->add_laser_calibrations());
  wod::Context::Stats* s = context->mutable_stats();
  WriteCounts(stats.laser_object_counts, s->mutable_laser_object_counts());
  WriteCounts(stats.camera_object_counts, s->mutable_camera_object_counts());
  s->set_time_of_day(stats.time_of_day);
  s->set_location(stats.location);
  s->set_weather(stats.weather);
  out.set_timestamp_micros(frame.timestamp_micros);
  WriteTransform(frame.world_from_vehicle, out.mutable_pose());
  for (const WaymoCameraImage& image : frame.images)
    WriteCameraImage(image, out.add_images());
  for (const WaymoLaser& laser : frame.lasers)
    WriteLaser(laser, out.add_lasers());
  for (const WaymoBox3d& box : frame.laser_labels)
    WriteBox3d(box, out.add_laser_labels());
  for (const WaymoCameraLabels& labels : frame.projected_lidar_labels)
    WriteCameraLabels(labels, out.add_projected_lidar_labels());
  for (const WaymoCameraLabels& labels : frame.camera_labels)
    WriteCameraLabels(labels, out.add_camera_labels());
  std::string bytes;
  // Deterministic: no maps in these messages; fields in number order.
  GEODRIVE_CHECK_INPUT(out.SerializeToString(&bytes),
                       "SerializeWaymoFrame: cannot serialize the frame of ",
                       frame.context_name);
  return bytes;
}

}  // namespace geodrive
