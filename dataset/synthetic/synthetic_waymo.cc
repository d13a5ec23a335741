#include "dataset/synthetic/synthetic_waymo.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

#include "dataset/waymo/tfrecord.h"
#include "dataset/waymo/waymo_range_image.h"
#include "dataset/waymo/waymo_writer.h"
#include "geometry/image_io.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {

namespace {

// Waymo's TOP range image height and the labels' range.
constexpr int kTopRows = 64;
constexpr double kLabelRangeM = 75.0;

// A Waymo-like rig: yaw of the optical axis (degrees, left positive), the
// position in the vehicle frame and the trigger offset after the frame time.
struct RigSpec {
  WaymoCameraName name;
  double yaw_deg;
  double x, y, z;
  bool side;
  double time_offset_s;
};
constexpr RigSpec kRig[] = {
    {WaymoCameraName::kFront, 0, 1.54, -0.02, 2.12, false, 0.025},
    {WaymoCameraName::kFrontLeft, 45, 1.50, 0.09, 2.12, false, 0.020},
    {WaymoCameraName::kFrontRight, -45, 1.50, -0.10, 2.12, false, 0.030},
    {WaymoCameraName::kSideLeft, 90, 1.43, 0.11, 2.11, true, 0.015},
    {WaymoCameraName::kSideRight, -90, 1.43, -0.11, 2.11, true, 0.035},
};

WaymoCameraCalibration CalibrationOf(const SyntheticWaymoCamera& c) {
  WaymoCameraCalibration out;
  out.name = c.name;
  out.intrinsics.f_u = c.camera.fx;
  out.intrinsics.f_v = c.camera.fy;
  out.intrinsics.c_u = c.camera.cx;
  out.intrinsics.c_v = c.camera.cy;
  out.width = c.camera.width;
  out.height = c.camera.height;
  out.vehicle_from_camera = c.ego_from_camera.ToMatrix();
  out.rolling_shutter = WaymoRollingShutter::kGlobalShutter;
  return out;
}

// The vehicle's velocity in the world frame at t (central differences).
void VehicleVelocity(const SyntheticWorld& world,
                     double t,
                     Eigen::Vector3d* linear,
                     Eigen::Vector3d* angular) {
  constexpr double h = 0.005;
  const Rigid3d a = world.GlobalFromEgo(t - h), b = world.GlobalFromEgo(t + h);
  *linear = (b.translation - a.translation) / (2 * h);
  const Eigen::AngleAxisd d(b.rotation * a.rotation.inverse());
  *angular = d.axis() * d.angle() / (2 * h);
}

// The vehicles within kLabelRangeM of the vehicle at t, in the vehicle frame.
std::vector<WaymoBox3d> LaserLabels(const SyntheticWorld& world,
                                    const Rigid3d& global_from_vehicle,
                                    double t) {
  const Rigid3d vehicle_from_global = global_from_vehicle.Inverse();
  std::vector<WaymoBox3d> boxes;
  for (const VehicleBox& v : world.Vehicles(t)) {
    const Eigen::Vector3d center = vehicle_from_global * v.center;
    if (center.head<2>().norm() > kLabelRangeM) continue;
    const Eigen::Matrix3d R =
        (vehicle_from_global.rotation * v.rotation).toRotationMatrix();
    WaymoBox3d box;
    box.id = SyntheticWaymoLabelId(v.id);
    box.type = WaymoObjectType::kVehicle;
    box.center = center;
    box.width = v.size_wlh.x();
    box.length = v.size_wlh.y();
    box.height = v.size_wlh.z();
    box.heading = std::atan2(R(1, 0), R(0, 0));
    boxes.push_back(box);
  }
  return boxes;
}

// A 2D box over [x0, x1] x [y0, y1] (pixel coordinates, kIntegerIndex).
WaymoBox2d Box2d(
    const std::string& id, double x0, double x1, double y0, double y1) {
  WaymoBox2d b;
  b.id = id;
  b.type = WaymoObjectType::kVehicle;
  b.center_x = 0.5 * (x0 + x1);
  b.center_y = 0.5 * (y0 + y1);
  b.size_x = x1 - x0;
  b.size_y = y1 - y0;
  return b;
}

// projected_lidar_labels: the box of the 8 projected corners clipped to the
// image ([-0.5, W - 0.5] x [-0.5, H - 0.5]); boxes with a corner behind the
// camera or outside the image are left out. The corners (vehicle frame at the
// frame pose `world_from_vehicle`) go through the world to the camera at its
// image's pose, as Waymo projects its labels with each camera's own pose.
WaymoCameraLabels ProjectedLabels(const WaymoCameraCalibration& camera,
                                  const WaymoCameraImage& image,
                                  const Eigen::Matrix4d& world_from_vehicle,
                                  const std::vector<WaymoBox3d>& boxes) {
  WaymoCameraLabels out;
  out.name = camera.name;
  const Eigen::Matrix4d camera_from_vehicle =
      camera.vehicle_from_camera.inverse() *
      image.world_from_vehicle.inverse() * world_from_vehicle;
  for (const WaymoBox3d& box : boxes) {
    Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
    bool behind = false;
    for (const Eigen::Vector3d& corner : WaymoBoxCorners(box)) {
      const Eigen::Vector3d p =
          (camera_from_vehicle * corner.homogeneous()).head<3>();
      Eigen::Vector2d px;
      if (ProjectWaymoCamera(camera, p, &px) != WaymoProjection::kValid) {
        behind = true;
        break;
      }
      lo = lo.cwiseMin(px);
      hi = hi.cwiseMax(px);
    }
    if (behind) continue;
    lo = lo.cwiseMax(Eigen::Vector2d(-0.5, -0.5));
    hi = hi.cwiseMin(Eigen::Vector2d(camera.width - 0.5, camera.height - 0.5));
    if (!(hi.x() > lo.x() && hi.y() > lo.y())) continue;
    out.boxes.push_back(Box2d(box.id + "_" + ToString(camera.name), lo.x(),
                              hi.x(), lo.y(), hi.y()));
  }
  return out;
}

// camera_labels: the pixels each labelled vehicle covers in the rendered
// instance image (the box of their edges).
WaymoCameraLabels VisibleLabels(WaymoCameraName name,
                                const cv::Mat& instance,
                                const std::vector<WaymoBox3d>& boxes) {
  std::map<int, cv::Rect> extent;
  for (int v = 0; v < instance.rows; ++v) {
    const uint16_t* row = instance.ptr<uint16_t>(v);
    for (int u = 0; u < instance.cols; ++u) {
      if (row[u] == kStaticInstance || row[u] == kSkyInstance) continue;
      auto [it, fresh] = extent.try_emplace(row[u], u, v, 1, 1);
      if (!fresh) it->second |= cv::Rect(u, v, 1, 1);
    }
  }
  WaymoCameraLabels out;
  out.name = name;
  for (const WaymoBox3d& box : boxes) {
    for (const auto& [value, rect] : extent) {
      if (SyntheticWaymoLabelId(value - 1) != box.id) continue;
      out.boxes.push_back(Box2d(box.id + "_" + ToString(name), rect.x - 0.5,
                                rect.x + rect.width - 0.5, rect.y - 0.5,
                                rect.y + rect.height - 0.5));
    }
  }
  return out;
}

// The frame pose as TOP's pose-image channels: roll, pitch, yaw, x, y, z
// (rotation Rz(yaw) Ry(pitch) Rx(roll)).
std::array<float, 6> PoseChannels(const Rigid3d& pose) {
  const Eigen::Matrix3d R = pose.rotation.toRotationMatrix();
  const Eigen::Vector3d& t = pose.translation;
  return {static_cast<float>(std::atan2(R(2, 1), R(2, 2))),
          static_cast<float>(std::asin(std::clamp(-R(2, 0), -1.0, 1.0))),
          static_cast<float>(std::atan2(R(1, 0), R(0, 0))),
          static_cast<float>(t.x()),
          static_cast<float>(t.y()),
          static_cast<float>(t.z())};
}

// TOP's first return: CastLidar's ray a in a frame yawed by
// pi - pi / W from the laser's is column (W - a) mod W of Waymo's layout
// (column c looks at pi - 2 pi (c + 0.5) / W); ring r is row 63 - r.
WaymoLaser CastTop(const SyntheticWorld& world,
                   const SyntheticWaymoOptions& options,
                   const Rigid3d& global_from_vehicle,
                   double t,
                   int64_t* num_returns) {
  const int W = options.lidar_columns, H = kTopRows;
  const Rigid3d vehicle_from_laser =
      Rigid3d::FromMatrix(SyntheticWaymoTopCalibration().vehicle_from_laser);
  const Rigid3d laser_from_cast(Eigen::Quaterniond(Eigen::AngleAxisd(
                                    M_PI - M_PI / W, Eigen::Vector3d::UnitZ())),
                                Eigen::Vector3d::Zero());
  const LidarSweep sweep = world.CastLidar(
      global_from_vehicle * vehicle_from_laser * laser_from_cast, t,
      SyntheticWaymoLidarOptions(options));
  WaymoRangeImage image;
  image.height = H;
  image.width = W;
  image.channels = 4;
  image.values.assign(static_cast<size_t>(H) * W * 4, 0.0f);
  for (size_t i = 0; i < image.values.size(); i += 4) {
    image.values[i] = -1.0f;      // no return
    image.values[i + 3] = -1.0f;  // not in a no-label zone
  }
  for (size_t i = 0; i < sweep.points.size(); ++i) {
    const Eigen::Vector3d p = sweep.points[i].cast<double>();
    long a = std::lround(std::atan2(p.y(), p.x()) * W / (2 * M_PI));
    a = ((a % W) + W) % W;
    const int col = static_cast<int>((W - a) % W);
    const int row = H - 1 - static_cast<int>(sweep.ring[i]);
    float* px = &image.values[(static_cast<size_t>(row) * W + col) * 4];
    px[0] = static_cast<float>(p.norm());
    px[1] = sweep.intensity[i] / 255.0f;
    px[2] = 0.0f;
  }
  *num_returns += static_cast<int64_t>(sweep.points.size());
  WaymoRangeImage pose;
  pose.height = H;
  pose.width = W;
  pose.channels = 6;
  const std::array<float, 6> channels = PoseChannels(global_from_vehicle);
  pose.values.reserve(static_cast<size_t>(H) * W * 6);
  for (int k = 0; k < H * W; ++k)
    pose.values.insert(pose.values.end(), channels.begin(), channels.end());
  WaymoLaser laser;
  laser.name = WaymoLaserName::kTop;
  laser.return1 = CompressWaymoRangeImage(image);
  laser.top_pose = CompressWaymoRangeImage(pose);
  return laser;
}

// One camera's image (rendered at its trigger time with its own pose) and
// its camera_labels.
void RenderWaymoCamera(const SyntheticWorld& world,
                       const SyntheticWaymoOptions& options,
                       const SyntheticWaymoCamera& cam,
                       int64_t frame_us,
                       double t,
                       const std::vector<WaymoBox3d>& boxes,
                       WaymoFrame* frame) {
  const double tc = t + cam.time_offset_s;
  const Rigid3d global_from_vehicle = world.GlobalFromEgo(tc);
  const RenderedView view = world.RenderCamera(
      cam.camera, global_from_vehicle * cam.ego_from_camera, tc);
  WaymoCameraImage image;
  image.name = cam.name;
  const std::vector<uint8_t> jpeg = EncodeJpegRgb(
      view.rgb, options.jpeg_quality, "synthetic " + ToString(cam.name));
  image.jpeg.assign(jpeg.begin(), jpeg.end());
  image.has_pose = true;
  image.world_from_vehicle = global_from_vehicle.ToMatrix();
  image.has_velocity = true;
  VehicleVelocity(world, tc, &image.linear_velocity, &image.angular_velocity);
  const double seconds =
      (frame_us + std::llround(cam.time_offset_s * 1e6)) * 1e-6;
  image.pose_timestamp = seconds;
  image.shutter = 0.005;
  image.camera_trigger_time = seconds;
  image.camera_readout_done_time = seconds + image.shutter;
  frame->images.push_back(std::move(image));
  frame->camera_labels.push_back(VisibleLabels(cam.name, view.instance, boxes));
}

std::vector<std::pair<WaymoObjectType, int>> VehicleCount(int n) {
  if (n == 0) return {};
  return {{WaymoObjectType::kVehicle, n}};
}

// One frame of scene `scene` as the serialized `Frame`.
std::string MakeWaymoFrame(const SyntheticWorld& world,
                           const SyntheticWaymoOptions& options,
                           const std::vector<SyntheticWaymoCamera>& rig,
                           int scene,
                           int index,
                           SyntheticWaymoSummary* summary) {
  const double t = SyntheticWaymoFrameSeconds(index);
  const Rigid3d global_from_vehicle = world.GlobalFromEgo(t);
  WaymoFrame frame;
  frame.context_name = SyntheticWaymoContextName(options, scene);
  frame.timestamp_micros = SyntheticWaymoTimestampMicros(options, scene, index);
  frame.world_from_vehicle = global_from_vehicle.ToMatrix();
  frame.laser_labels = LaserLabels(world, global_from_vehicle, t);
  for (const SyntheticWaymoCamera& cam : rig) {
    frame.camera_calibrations.push_back(CalibrationOf(cam));
    RenderWaymoCamera(world, options, cam, frame.timestamp_micros, t,
                      frame.laser_labels, &frame);
    frame.projected_lidar_labels.push_back(
        ProjectedLabels(frame.camera_calibrations.back(), frame.images.back(),
                        frame.world_from_vehicle, frame.laser_labels));
  }
  frame.laser_calibrations.push_back(SyntheticWaymoTopCalibration());
  frame.lasers.push_back(CastTop(world, options, global_from_vehicle, t,
                                 &summary->num_lidar_returns));
  WaymoContextStats stats;
  stats.time_of_day = "Day";
  stats.location = "location_synthetic";
  stats.weather = "sunny";
  stats.laser_object_counts =
      VehicleCount(static_cast<int>(frame.laser_labels.size()));
  int camera_objects = 0;
  for (const WaymoCameraLabels& labels : frame.camera_labels)
    camera_objects += static_cast<int>(labels.boxes.size());
  stats.camera_object_counts = VehicleCount(camera_objects);
  summary->num_images += static_cast<int64_t>(frame.images.size());
  summary->num_laser_labels += static_cast<int64_t>(frame.laser_labels.size());
  return SerializeWaymoFrame(frame, stats);
}

// Writes scene `scene`'s segment file, frame by frame.
void WriteWaymoScene(const SyntheticWaymoOptions& options,
                     const std::vector<SyntheticWaymoCamera>& rig,
                     int scene,
                     const std::string& path,
                     SyntheticWaymoSummary* summary) {
  const SyntheticWorld world(SyntheticWaymoWorldOptions(options, scene));
  const std::string tmp = TemporaryPathFor(path);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    GEODRIVE_CHECK_INPUT(out.good(), tmp, ": cannot create the file");
    const int n = SyntheticWaymoNumFrames(options);
    std::string record;
    for (int i = 0; i < n; ++i) {
      record.clear();
      AppendTfRecord(MakeWaymoFrame(world, options, rig, scene, i, summary),
                     &record);
      out.write(record.data(), static_cast<std::streamsize>(record.size()));
      summary->num_bytes += static_cast<int64_t>(record.size());
      ++summary->num_frames;
      if (options.progress && ((i + 1) % 10 == 0 || i + 1 == n)) {
        options.progress(SyntheticWaymoFileName(options, scene) + ": " +
                         std::to_string(i + 1) + "/" + std::to_string(n) +
                         " frames");
      }
    }
    out.flush();
    GEODRIVE_CHECK_INPUT(out.good(), tmp, ": write failed");
  }
  CommitTemporaryFile(tmp, path);
}

}  // namespace

std::string SyntheticWaymoOptions::Validate() const {
  std::ostringstream os;
  if (num_scenes < 1 || num_scenes > 10000) {
    os << "num_scenes must be in [1, 10000]";
  } else if (image_width < 16 || image_width > 16384 || image_height < 16 ||
             image_height > 16384) {
    os << "image size must be in [16, 16384] per side (got " << image_width
       << "x" << image_height << ")";
  } else if (!(scene_duration_s >= 1.0 && scene_duration_s <= 3600.0)) {
    os << "scene duration must be in [1, 3600] s (got " << scene_duration_s
       << ")";
  } else if (lidar_columns < 16 || lidar_columns > 100000) {
    os << "lidar_columns must be in [16, 100000]";
  } else if (jpeg_quality < 1 || jpeg_quality > 100) {
    os << "jpeg_quality must be in [1, 100]";
  }
  return os.str();
}

std::string SyntheticWaymoSummary::BriefReport() const {
  std::ostringstream os;
  os << files.size() << " segment file(s), " << num_frames << " frames, "
     << num_images << " camera images, " << num_laser_labels
     << " laser_labels, " << num_lidar_returns << " TOP returns, " << num_bytes
     << " bytes in " << seconds << " s";
  return os.str();
}

std::vector<SyntheticWaymoCamera> SyntheticWaymoRig(
    const SyntheticWaymoOptions& options) {
  const int W = options.image_width, H = options.image_height;
  const int side_height =
      std::max(1, static_cast<int>(std::lround(H * 886.0 / 1280.0)));
  const double fx = 2055.0 * W / 1920.0, fy = 2055.0 * H / 1280.0;
  std::vector<SyntheticWaymoCamera> rig;
  for (const RigSpec& s : kRig) {
    SyntheticWaymoCamera c;
    c.name = s.name;
    const int h = s.side ? side_height : H;
    c.camera = PinholeCamera(fx, fy, 0.5 * W - 0.5, 0.5 * h - 0.5, W, h);
    Eigen::Matrix4d vehicle_from_waymo_camera = Eigen::Matrix4d::Identity();
    vehicle_from_waymo_camera.topLeftCorner<3, 3>() =
        Eigen::AngleAxisd(s.yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ())
            .toRotationMatrix();
    vehicle_from_waymo_camera.topRightCorner<3, 1>() =
        Eigen::Vector3d(s.x, s.y, s.z);
    c.ego_from_camera =
        Rigid3d::FromMatrix(VehicleFromOpenCvCamera(vehicle_from_waymo_camera));
    c.time_offset_s = s.time_offset_s;
    rig.push_back(c);
  }
  return rig;
}

LidarOptions SyntheticWaymoLidarOptions(const SyntheticWaymoOptions& options) {
  LidarOptions lidar;
  lidar.num_rings = kTopRows;
  lidar.min_elevation_deg = -17.6;
  lidar.max_elevation_deg = 2.4;
  lidar.azimuth_steps = options.lidar_columns;
  lidar.min_range_m = 1.0;
  lidar.max_range_m = 75.0;
  return lidar;
}

WaymoLaserCalibration SyntheticWaymoTopCalibration() {
  const LidarOptions lidar =
      SyntheticWaymoLidarOptions(SyntheticWaymoOptions());
  WaymoLaserCalibration top;
  top.name = WaymoLaserName::kTop;
  const int nr = lidar.num_rings;
  for (int r = 0; r < nr; ++r) {
    // The elevation of CastLidar's ring r, computed as it does.
    top.beam_inclinations.push_back(
        (lidar.min_elevation_deg +
         (lidar.max_elevation_deg - lidar.min_elevation_deg) * r / (nr - 1)) *
        M_PI / 180.0);
  }
  top.beam_inclination_min = top.beam_inclinations.front();
  top.beam_inclination_max = top.beam_inclinations.back();
  top.vehicle_from_laser.topRightCorner<3, 1>() =
      Eigen::Vector3d(1.43, 0.0, 2.184);
  return top;
}

int SyntheticWaymoNumFrames(const SyntheticWaymoOptions& options) {
  return std::max(
      1, static_cast<int>(std::floor(
             options.scene_duration_s * kSyntheticWaymoFrameRateHz + 1e-9)));
}

double SyntheticWaymoFrameSeconds(int frame_index) {
  return static_cast<double>(frame_index) / kSyntheticWaymoFrameRateHz;
}

int64_t SyntheticWaymoTimestampMicros(const SyntheticWaymoOptions& options,
                                      int scene_index,
                                      int frame_index) {
  const int64_t span_us =
      static_cast<int64_t>(std::ceil(options.scene_duration_s)) * 1000000;
  const int64_t start_us =
      1700000000000000LL +
      static_cast<int64_t>(scene_index) * (span_us + 60000000LL) +
      static_cast<int64_t>(options.seed % 1000) * 1000;
  return start_us + static_cast<int64_t>(frame_index) *
                        (1000000 / kSyntheticWaymoFrameRateHz);
}

SyntheticWorldOptions SyntheticWaymoWorldOptions(
    const SyntheticWaymoOptions& options, int scene_index) {
  SyntheticWorldOptions w;
  w.seed = options.seed;
  w.scene_index = scene_index;
  w.duration_s = options.scene_duration_s;
  w.reverse_after_stop = options.reverse_after_stop;
  return w;
}

std::string SyntheticWaymoContextName(const SyntheticWaymoOptions& options,
                                      int scene_index) {
  const long long ms = std::llround(options.scene_duration_s * 1000);
  return "synthetic_" + std::to_string(options.seed) + "_" +
         std::to_string(scene_index) + "_000_" + std::to_string(ms);
}

std::string SyntheticWaymoFileName(const SyntheticWaymoOptions& options,
                                   int scene_index) {
  return "segment-" + SyntheticWaymoContextName(options, scene_index) +
         "_with_camera_labels.tfrecord";
}

std::string SyntheticWaymoLabelId(int vehicle_id) {
  return "synthetic_vehicle_" + std::to_string(vehicle_id);
}

SyntheticWaymoSummary WriteSyntheticWaymo(const SyntheticWaymoOptions& options,
                                          const std::string& out_dir) {
  const std::string err = options.Validate();
  GEODRIVE_CHECK_INPUT(err.empty(), "synthetic Waymo: ", err);
  const auto start = std::chrono::steady_clock::now();
  CreateOutputDirectory(out_dir);
  const std::vector<SyntheticWaymoCamera> rig = SyntheticWaymoRig(options);
  SyntheticWaymoSummary summary;
  for (int scene = 0; scene < options.num_scenes; ++scene) {
    const std::string path =
        out_dir + "/" + SyntheticWaymoFileName(options, scene);
    WriteWaymoScene(options, rig, scene, path, &summary);
    summary.files.push_back(path);
  }
  summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  return summary;
}

}  // namespace geodrive
