// The Waymo Open Dataset v1 adapter: TFRecord segments of `Frame` protos
// (dataset/waymo/) -> DriveClip.
//
// DriveDatasetOptions::root is a folder of *.tfrecord segments (sorted by file
// name) or one .tfrecord file; one segment is one scene, named by its context
// name. Channels are Waymo's camera names (FRONT, FRONT_LEFT, FRONT_RIGHT,
// SIDE_LEFT, SIDE_RIGHT); "CAM_FRONT" and the like are accepted and read as
// "FRONT" (so the nuScenes default channel works). Every Waymo frame is an
// annotated keyframe (10 Hz); clips are SelectChainClips over the segment's
// frames in time order.
//
// Per frame: world_from_ego is the camera image's own vehicle pose at its own
// time (CameraImage.pose and pose_timestamp; nuScenes' rule: a camera's pose
// is its own ego pose, never the LiDAR's) where the frame stores one, the
// frame pose (vehicle -> world) otherwise;
// ego_from_cam the camera's extrinsic in OpenCV axes (VehicleFromOpenCvCamera),
// the camera Waymo's f_u f_v c_u c_v. A frame's image is the path
// "<segment>.tfrecord#<record>:<CAMERA>", which the image readers
// (geometry/image_io.h) resolve through the resolver registered here: the
// record's JPEG, undistorted to the pinhole camera (Waymo's k1 k2 p1 p2 k3,
// the forward model of ProjectWaymoCamera evaluated at every output pixel and
// sampled bilinearly, cv::remap; pixels whose radial factor leaves Waymo's
// trusted [0.8, 1.2] are black) and handed over as a PNG. With zero
// distortion the JPEG goes through as stored.
//
// Boxes are `laser_labels` moved to the world frame, ids kept across frames,
// types mapped to nuScenes-style categories (WaymoCategory). LiDAR: when a
// segment's frames hold range images, one sweep per frame (every laser's
// first and second return, in the vehicle frame at the frame pose); when none
// does, Describe() says "no range images: LiDAR geometry unavailable".

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "dataset/clips.h"
#include "dataset/drive_dataset.h"
#include "dataset/internal/adapters.h"
#include "dataset/waymo/tfrecord.h"
#include "dataset/waymo/waymo_frame.h"
#include "dataset/waymo/waymo_range_image.h"
#include "geometry/image_io.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace fs = std::filesystem;
namespace {

// One frame's metadata (no image bytes, no range images).
struct WaymoFrameInfo {
  std::string file;  // the segment file (absolute)
  int64_t record = 0;
  int64_t timestamp_us = 0;
  Rigid3d world_from_vehicle;
  std::vector<WaymoCameraCalibration> cameras;
  // Per camera with a stored CameraImage.pose: the vehicle pose at the
  // image's own time and that time (microseconds).
  std::map<std::string, std::pair<Rigid3d, int64_t>> image_poses;
  std::vector<ClipBox> boxes;
  bool has_range_images = false;
};

struct WaymoSegment {
  std::string name;  // context name
  std::string file;
  std::vector<WaymoFrameInfo> frames;  // time order
  bool has_range_images = false;
};

// "CAM_FRONT" -> "FRONT"; Waymo names as they are.
std::string WaymoChannel(const std::string& channel) {
  return channel.rfind("CAM_", 0) == 0 ? channel.substr(4) : channel;
}

// nuScenes-style category of a Waymo label type: VEHICLE "vehicle.car",
// PEDESTRIAN "human.pedestrian.adult", CYCLIST "vehicle.bicycle" (nuScenes
// annotates a bicycle with its rider), SIGN "static_object.sign", else "".
std::string WaymoCategory(WaymoObjectType type) {
  switch (type) {
    case WaymoObjectType::kVehicle:
      return "vehicle.car";
    case WaymoObjectType::kPedestrian:
      return "human.pedestrian.adult";
    case WaymoObjectType::kCyclist:
      return "vehicle.bicycle";
    case WaymoObjectType::kSign:
      return "static_object.sign";
    case WaymoObjectType::kUnknown:
      break;
  }
  return "";
}

std::vector<ClipBox> WorldBoxes(const WaymoFrame& frame) {
  const Eigen::Matrix4d& T = frame.world_from_vehicle;
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  std::vector<ClipBox> out;
  for (const WaymoBox3d& b : frame.laser_labels) {
    ClipBox c;
    c.instance_id = b.id;
    c.category = WaymoCategory(b.type);
    c.box.center = R * b.center + T.topRightCorner<3, 1>();
    c.box.size = Eigen::Vector3d(b.width, b.length, b.height);
    c.box.rotation = Eigen::Quaterniond(
        R * Eigen::AngleAxisd(b.heading, Eigen::Vector3d::UnitZ()).matrix());
    c.box.rotation.normalize();
    out.push_back(std::move(c));
  }
  return out;
}

WaymoSegment ReadSegment(const std::string& file) {
  WaymoSegment seg;
  seg.file = file;
  TfRecordReader reader(file);
  std::string data;
  while (true) {
    const int64_t record = reader.index();
    if (!reader.Next(&data)) break;
    const WaymoFrame frame = ParseWaymoFrame(data, file, record);
    WaymoFrameInfo info;
    info.file = file;
    info.record = record;
    info.timestamp_us = frame.timestamp_micros;
    info.world_from_vehicle = Rigid3d::FromMatrix(frame.world_from_vehicle);
    info.cameras = frame.camera_calibrations;
    for (const WaymoCameraImage& image : frame.images) {
      if (!image.has_pose) continue;
      const int64_t t_us =
          image.pose_timestamp > 0
              ? static_cast<int64_t>(std::llround(image.pose_timestamp * 1e6))
              : frame.timestamp_micros;
      info.image_poses[ToString(image.name)] = {
          Rigid3d::FromMatrix(image.world_from_vehicle), t_us};
    }
    info.boxes = WorldBoxes(frame);
    info.has_range_images = frame.has_range_images;
    seg.has_range_images |= frame.has_range_images;
    if (seg.name.empty()) seg.name = frame.context_name;
    GEODRIVE_CHECK_INPUT(frame.context_name == seg.name, file, ": record ",
                         record, ": context '", frame.context_name,
                         "' differs from the segment's '", seg.name, "'");
    seg.frames.push_back(std::move(info));
  }
  GEODRIVE_CHECK_INPUT(!seg.frames.empty(), file, ": no frame records");
  if (seg.name.empty()) seg.name = fs::path(file).stem().string();
  std::stable_sort(seg.frames.begin(), seg.frames.end(),
                   [](const WaymoFrameInfo& a, const WaymoFrameInfo& b) {
                     return a.timestamp_us < b.timestamp_us;
                   });
  return seg;
}

// The record `record` of `file`, parsed.
WaymoFrame ReadRecord(const std::string& file, int64_t record) {
  TfRecordReader reader(file);
  for (int64_t i = 0; i < record; ++i)
    GEODRIVE_CHECK_INPUT(reader.Skip(), file, ": no record ", record);
  std::string data;
  GEODRIVE_CHECK_INPUT(reader.Next(&data), file, ": no record ", record);
  return ParseWaymoFrame(data, file, record);
}

// The remap tables of `camera` (the forward model at every output pixel,
// fixed-point as cv::convertMaps makes them), computed once per calibration
// and kept for the process (about 14 MB for a 1920x1280 camera).
std::shared_ptr<const std::pair<cv::Mat, cv::Mat>> UndistortMaps(
    const WaymoCameraCalibration& camera) {
  static std::mutex mutex;
  static std::map<std::vector<double>,
                  std::shared_ptr<const std::pair<cv::Mat, cv::Mat>>>
      cache;
  const WaymoIntrinsics& k = camera.intrinsics;
  const std::vector<double> key = {k.f_u,
                                   k.f_v,
                                   k.c_u,
                                   k.c_v,
                                   k.k1,
                                   k.k2,
                                   k.p1,
                                   k.p2,
                                   k.k3,
                                   double(camera.width),
                                   double(camera.height)};
  {
    std::lock_guard<std::mutex> lock(mutex);
    const auto it = cache.find(key);
    if (it != cache.end()) return it->second;
  }
  cv::Mat map_x(camera.height, camera.width, CV_32FC1);
  cv::Mat map_y(camera.height, camera.width, CV_32FC1);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const double x = (u - k.c_u) / k.f_u, y = (v - k.c_v) / k.f_v;
      const double r2 = x * x + y * y;
      const double radial = 1 + r2 * (k.k1 + r2 * (k.k2 + r2 * k.k3));
      float sx = -1e4f, sy = -1e4f;  // outside: black
      if (radial >= 0.8 && radial <= 1.2) {
        const double xd =
            x * radial + 2 * k.p1 * x * y + k.p2 * (r2 + 2 * x * x);
        const double yd =
            y * radial + k.p1 * (r2 + 2 * y * y) + 2 * k.p2 * x * y;
        sx = static_cast<float>(k.f_u * xd + k.c_u);
        sy = static_cast<float>(k.f_v * yd + k.c_v);
      }
      map_x.at<float>(v, u) = sx;
      map_y.at<float>(v, u) = sy;
    }
  }
  auto maps = std::make_shared<std::pair<cv::Mat, cv::Mat>>();
  cv::convertMaps(map_x, map_y, maps->first, maps->second, CV_16SC2);
  std::lock_guard<std::mutex> lock(mutex);
  return cache.emplace(key, std::move(maps)).first->second;
}

// The image of `camera` undistorted to its pinhole camera (see the file
// comment); `rgb` is the decoded JPEG.
cv::Mat UndistortToPinhole(const cv::Mat& rgb,
                           const WaymoCameraCalibration& camera) {
  const auto maps = UndistortMaps(camera);
  cv::Mat out;
  cv::remap(rgb, out, maps->first, maps->second, cv::INTER_LINEAR,
            cv::BORDER_CONSTANT, cv::Scalar(0, 0, 0));
  return out;
}

bool HasDistortion(const WaymoIntrinsics& k) {
  return k.k1 != 0 || k.k2 != 0 || k.p1 != 0 || k.p2 != 0 || k.k3 != 0;
}

// The image resolver for "<file>.tfrecord#<record>:<CAMERA>".
bool ResolveWaymoImage(const std::string& path, std::vector<uint8_t>* bytes) {
  const size_t hash = path.rfind('#');
  if (hash == std::string::npos) return false;
  const std::string file = path.substr(0, hash);
  if (file.size() < 9 || file.compare(file.size() - 9, 9, ".tfrecord") != 0)
    return false;
  const size_t colon = path.find(':', hash);
  if (colon == std::string::npos) return false;
  int64_t record = 0;
  try {
    record = std::stoll(path.substr(hash + 1, colon - hash - 1));
  } catch (const std::exception&) {
    return false;
  }
  const std::string camera = path.substr(colon + 1);
  const WaymoFrame frame = ReadRecord(file, record);
  const WaymoCameraImage* image = nullptr;
  const WaymoCameraCalibration* calib = nullptr;
  for (const WaymoCameraImage& i : frame.images)
    if (ToString(i.name) == camera) image = &i;
  for (const WaymoCameraCalibration& c : frame.camera_calibrations)
    if (ToString(c.name) == camera) calib = &c;
  GEODRIVE_CHECK_INPUT(image != nullptr && calib != nullptr, path,
                       ": the frame has no image and calibration of camera ",
                       camera);
  bytes->assign(image->jpeg.begin(), image->jpeg.end());
  if (!HasDistortion(calib->intrinsics)) return true;
  const cv::Mat rgb = DecodeImageRgb(ImageFile{path, *bytes});
  GEODRIVE_CHECK_INPUT(rgb.cols == calib->width && rgb.rows == calib->height,
                       path, ": image is ", rgb.cols, "x", rgb.rows,
                       ", calibration says ", calib->width, "x", calib->height);
  *bytes = EncodePngImage(UndistortToPinhole(rgb, *calib));
  return true;
}

// One sweep per frame of a segment with range images.
class WaymoLidar : public LidarProvider {
 public:
  explicit WaymoLidar(std::shared_ptr<const WaymoSegment> segment)
      : segment_(std::move(segment)) {
    for (const WaymoFrameInfo& f : segment_->frames) {
      frames_.push_back(&f);
      LidarSweepInfo info;
      info.relative_path =
          fs::path(f.file).filename().string() + "#" + std::to_string(f.record);
      info.timestamp_us = f.timestamp_us;
      info.world_from_ego = f.world_from_vehicle;
      sweeps_.push_back(std::move(info));
    }
  }
  const std::vector<LidarSweepInfo>& Sweeps() const override { return sweeps_; }
  // Every laser's returns, vehicle frame (ego_from_sensor is the identity).
  PointCloud Load(size_t index) const override {
    const WaymoFrameInfo& f = *frames_.at(index);
    const WaymoFrame frame = ReadRecord(f.file, f.record);
    PointCloud cloud;
    for (const WaymoLaser& laser : frame.lasers) {
      const WaymoLaserCalibration* calib = nullptr;
      for (const WaymoLaserCalibration& c : frame.laser_calibrations)
        if (c.name == laser.name) calib = &c;
      if (calib == nullptr) continue;
      const std::string what = "laser " + ToString(laser.name);
      WaymoRangeImage pose;
      if (!laser.top_pose.empty())
        pose = DecodeWaymoRangeImage(laser.top_pose, 6, f.file, f.record,
                                     what + " pose");
      for (const std::string* ret : {&laser.return1, &laser.return2}) {
        if (ret->empty()) continue;
        const WaymoRangeImage image =
            DecodeWaymoRangeImage(*ret, 4, f.file, f.record, what);
        for (const Eigen::Vector3d& p : WaymoRangeImagePoints(
                 image, *calib, laser.top_pose.empty() ? nullptr : &pose,
                 frame.world_from_vehicle))
          cloud.positions.push_back(p.cast<float>());
      }
    }
    return cloud;
  }
  std::vector<ClipBox> Boxes(size_t index) const override {
    return frames_.at(index)->boxes;
  }

 private:
  std::shared_ptr<const WaymoSegment> segment_;  // frames_ point into it
  std::vector<const WaymoFrameInfo*> frames_;
  std::vector<LidarSweepInfo> sweeps_;
};

struct WaymoClipRef {
  size_t segment = 0;
  std::vector<int> frames;
};

class WaymoDriveDataset : public DriveDataset {
 public:
  explicit WaymoDriveDataset(const DriveDatasetOptions& options)
      : options_(options), channel_(WaymoChannel(options.channel)) {
    RegisterImageBytesResolver("waymo-tfrecord", ResolveWaymoImage);
    for (const std::string& file : SegmentFiles(options.root))
      segments_.push_back(std::make_shared<WaymoSegment>(ReadSegment(file)));
    ClipOptions co;
    co.channel = channel_;
    co.num_frames = options.clip_frames;
    co.stride = options.clip_stride;
    co.keyframes_only = options.frames == ClipFrameSource::kKeyframes;
    for (size_t s = 0; s < segments_.size(); ++s) {
      const WaymoSegment& seg = *segments_[s];
      std::vector<int64_t> ts;
      for (const WaymoFrameInfo& f : seg.frames) ts.push_back(f.timestamp_us);
      const std::vector<bool> keyframes(ts.size(), true);
      // Clip ids carry no dot (a file stem or context name may).
      std::string id_name = seg.name;
      std::replace(id_name.begin(), id_name.end(), '.', '_');
      for (ChainClip& c :
           SelectChainClips(id_name, ts, keyframes, co, &summary_)) {
        GEODRIVE_CHECK_INPUT(by_id_.count(c.id) == 0, seg.file, ": clip id '",
                             c.id, "' also comes from another segment");
        by_id_[c.id] = clips_.size();
        ids_.push_back(c.id);
        clips_.push_back({s, std::move(c.frames)});
      }
      if (seg.has_range_images) has_lidar_ = true;
    }
    ResolveRig();
  }

  std::string Describe() const override {
    std::ostringstream os;
    os << "waymo v1 at " << options_.root << ": " << segments_.size()
       << " segments, " << ids_.size() << " " << options_.clip_frames
       << "-frame " << channel_ << " clips; " << summary_.BriefReport()
       << (has_lidar_ ? "" : "; no range images: LiDAR geometry unavailable");
    return os.str();
  }
  const std::vector<std::string>& ClipIds() const override { return ids_; }
  bool HasLidar() const override { return has_lidar_; }

  DriveClip LoadClip(const std::string& id) const override {
    const auto it = by_id_.find(id);
    GEODRIVE_CHECK_INPUT(it != by_id_.end(), "'", id, "' is not a ",
                         options_.clip_frames, "-frame clip of ", options_.root,
                         " (stride ", options_.clip_stride,
                         "; see `geodrive clips --dataset waymo`)");
    const WaymoClipRef& ref = clips_[it->second];
    const WaymoSegment& seg = *segments_[ref.segment];
    DriveClip out;
    out.id = id;
    out.dataset = "waymo v1 at " + options_.root;
    out.scene_name = seg.name;
    out.scene_id = seg.name;
    out.channel = channel_;
    out.frame_source = options_.frames;
    std::shared_ptr<WaymoLidar> lidar;
    if (seg.has_range_images) {
      lidar = std::make_shared<WaymoLidar>(segments_[ref.segment]);
      out.lidar = lidar;
    }
    for (int i : ref.frames) out.frames.push_back(MakeFrame(seg, i, channel_));
    for (size_t k = 0; k < rig_.size(); ++k) {
      CameraStream stream;
      stream.channel = rig_[k];
      for (int i : ref.frames)
        stream.frames.push_back(MakeFrame(seg, i, rig_[k]));
      out.rig.push_back(std::move(stream));
    }
    out.provenance = {
        {"frames", channel_ + " camera of every frame record (10 Hz)"},
        {"poses", "Frame.pose * CameraCalibration.extrinsic (OpenCV axes)"},
        {"camera",
         "CameraCalibration.intrinsic f_u f_v c_u c_v; images undistorted "
         "to it (k1 k2 p1 p2 k3)"},
        {"boxes", "Frame.laser_labels in the world frame"},
        {"lidar", seg.has_range_images
                      ? "range images (first and second return) of the frame"
                      : "none (no range images)"}};
    return out;
  }

 private:
  static std::vector<std::string> SegmentFiles(const std::string& root) {
    std::vector<std::string> files;
    if (fs::is_regular_file(root)) {
      files.push_back(fs::absolute(root).string());
      return files;
    }
    GEODRIVE_CHECK_INPUT(fs::is_directory(root), root,
                         ": not a folder of .tfrecord segments nor a file");
    for (const auto& e : fs::directory_iterator(root))
      if (e.is_regular_file() && e.path().extension() == ".tfrecord")
        files.push_back(fs::absolute(e.path()).string());
    std::sort(files.begin(), files.end());
    GEODRIVE_CHECK_INPUT(!files.empty(), root, ": no *.tfrecord segment");
    return files;
  }

  DriveFrame MakeFrame(const WaymoSegment& seg,
                       int index,
                       const std::string& camera) const {
    const WaymoFrameInfo& f = seg.frames[index];
    const WaymoCameraCalibration* calib = nullptr;
    for (const WaymoCameraCalibration& c : f.cameras)
      if (ToString(c.name) == camera) calib = &c;
    GEODRIVE_CHECK_INPUT(calib != nullptr, f.file, ": record ", f.record,
                         ": no calibration of camera ", camera);
    DriveFrame out;
    const std::string member = "#" + std::to_string(f.record) + ":" + camera;
    out.frame_id =
        seg.name + "_" + std::to_string(f.timestamp_us) + "_" + camera;
    out.relative_path = fs::path(f.file).filename().string() + member;
    out.image_path = f.file + member;
    // Each camera at its own capture: the image's own vehicle pose and time
    // where the frame stores them (CameraImage.pose, pose_timestamp), the
    // frame's otherwise. The boxes stay at the frame (LiDAR) time.
    const auto own = f.image_poses.find(camera);
    out.timestamp_us =
        own != f.image_poses.end() ? own->second.second : f.timestamp_us;
    out.is_keyframe = true;
    out.world_from_ego =
        own != f.image_poses.end() ? own->second.first : f.world_from_vehicle;
    out.ego_from_cam = Rigid3d::FromMatrix(calib->vehicle_from_camera);
    out.world_from_cam = out.world_from_ego * out.ego_from_cam;
    const WaymoIntrinsics& k = calib->intrinsics;
    out.camera =
        PinholeCamera(k.f_u, k.f_v, k.c_u, k.c_v, calib->width, calib->height);
    out.boxes = f.boxes;
    if (seg.has_range_images) out.keyframe_sweep = static_cast<size_t>(index);
    return out;
  }

  // The rig's cameras from options_.cameras ("all": every camera of the
  // first frame, the reference first).
  void ResolveRig() {
    if (options_.cameras.empty() || segments_.empty()) return;
    const std::vector<WaymoCameraCalibration>& cams =
        segments_.front()->frames.front().cameras;
    if (options_.cameras.size() == 1 && options_.cameras[0] == "all") {
      rig_.push_back(channel_);
      for (const WaymoCameraCalibration& c : cams)
        if (ToString(c.name) != channel_) rig_.push_back(ToString(c.name));
    } else {
      for (const std::string& name : options_.cameras)
        rig_.push_back(WaymoChannel(name));
    }
    GEODRIVE_CHECK_INPUT(rig_.front() == channel_,
                         "--cameras: the list must hold the reference camera ",
                         channel_);
  }

  DriveDatasetOptions options_;
  std::string channel_;
  std::vector<std::shared_ptr<const WaymoSegment>> segments_;
  std::vector<WaymoClipRef> clips_;
  std::vector<std::string> ids_;
  std::map<std::string, size_t> by_id_;
  std::vector<std::string> rig_;
  ClipSelectionSummary summary_;
  bool has_lidar_ = false;
};

}  // namespace

std::unique_ptr<DriveDataset> OpenWaymoDriveDataset(
    const DriveDatasetOptions& options) {
  return std::make_unique<WaymoDriveDataset>(options);
}

}  // namespace geodrive
