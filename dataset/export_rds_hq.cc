// The rds-hq export (dataset/exporter.h): Cosmos-Drive-Dreams' RDS-HQ, the
// input of its condition renderer (nv-tlabs/Cosmos-Drive-Dreams,
// cosmos-drive-dreams-toolkits/render_from_rds_hq.py), as
// docs/reference/trainer-formats.md §3 cites it ("CDD" there). One webdataset
// tar per field and clip, each holding one sample whose members are
// `<clip>.<key>` (webdataset splits a member name at its first dot: clip ids
// with a dot are refused). Per clip, PAIR/rds_hq/<field>/<clip>.tar (linked
// as OUT/rds_hq/<field>/<clip>.tar):
//
//   pose/               %06d.pose.<camera>.npy  (4,4) float64 world_from_cam,
//                       OpenCV axes, one per frame 0..N-1 and camera
//                       (render_from_rds_hq.py:79-92,357)
//   pinhole_intrinsic/  pinhole_intrinsic.<camera>.npy (6,) float64
//                       [fx, fy, cx, cy, 1280, 720]: our camera
//                       centre-cropped to 16:9 at the renderer's
//                       RESIZE_RESOLUTION, so that it rescales nothing
//                       (utils/camera/pinhole.py:58-71)
//   lidar_raw/          %06d.lidar_raw.npz at every multiple of 3: xyz (N,3)
//                       float32 in the LiDAR's frame, lidar_to_world (4,4)
//                       float64 (render_from_rds_hq.py:314-342)
//   all_object_info/    %06d.all_object_info.json at every frame:
//                       {track: {object_to_world, object_lwh,
//                       object_is_moving, object_type}} (utils/bbox_utils.py)
//   3d_<type>/          <type>.json = {"labels": []} for the eight
//                       MINIMAP_TYPES: we have no HD map
//                       (config/dataset_rds_hq.json:3-12)
//
// <camera> is the config's name: camera_front_wide_120fov, the rds_hq
// config's one camera, for a single-camera pair (CAM_FRONT or another); for
// a rig (build-dataset --cameras all) the six nuScenes cameras under the six
// names of the rds_hq_mv config (config/dataset_rds_hq_mv.json:2), matched by
// where they look (kRigCameras). Poses, LiDAR and boxes share one world: the
// pair's (the reference camera at frame 0).
// Frames are written as they are, one pose per clip frame: the renderer
// takes them as 30 Hz (INPUT_POSE_FPS) and renders chunks of 121
// (TARGET_CHUNK_FRAME), so a clip needs at least 121 frames; nothing is
// resampled (a 12 Hz nuScenes clip plays 2.5 times faster than it was
// driven). The LiDAR keys sit on the 30 Hz index's multiples of 3
// (30 / INPUT_LIDAR_FPS 10), each the sweep nearest that frame's time.
// Finish: the links, and the clip-id JSON lists OUT/rds_hq/clips_train.json
// and clips_val.json (split by scene, --val-fraction) for the renderer's -cj.
//
// The tars are written here (a POSIX ustar writer, pax headers for member
// names over 100 bytes): no packaged tar library is among the toolkit's
// dependencies (libarchive is not), and one sample of a few files needs
// only the 512-byte header format. Members are dated 0 and owned by 0, so
// the same export gives the same bytes.

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>

#include "dataset/exporter.h"
#include "dataset/internal/exporters.h"
#include "dataset/pairs.h"
#include "geometry/npz.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace internal {
// Named: a unity build puts the exporters' files in one translation unit.
namespace rds_hq_export {
namespace {

namespace fs = std::filesystem;

constexpr int kChunkFrames = 121;  // TARGET_CHUNK_FRAME, dataset_rds_hq.json
constexpr double kPoseFps = 30;    // INPUT_POSE_FPS
constexpr int kLidarStep = 3;      // INPUT_POSE_FPS / INPUT_LIDAR_FPS
constexpr int kWidth = 1280, kHeight = 720;  // RESIZE_RESOLUTION
// The rds_hq config's one camera (dataset_rds_hq.json:2): a single-camera
// pair's camera.
constexpr char kCamera[] = "camera_front_wide_120fov";
// The rds_hq_mv config's six cameras (dataset_rds_hq_mv.json:2) and the
// nuScenes camera that looks the same way: the front and the two front-side
// cameras are the 120-degree ones, the two rear-side cameras the 70-degree
// ones, and CAM_BACK the rear (tele) camera.
constexpr const char* kRigCameras[][2] = {
    {"CAM_FRONT", "camera_front_wide_120fov"},
    {"CAM_FRONT_LEFT", "camera_cross_left_120fov"},
    {"CAM_FRONT_RIGHT", "camera_cross_right_120fov"},
    {"CAM_BACK_LEFT", "camera_rear_left_70fov"},
    {"CAM_BACK_RIGHT", "camera_rear_right_70fov"},
    {"CAM_BACK", "camera_rear_tele_30fov"}};
constexpr const char* kMinimapTypes[] = {
    "lanelines",  "road_boundaries", "crosswalks",    "road_markings",
    "wait_lines", "poles",           "traffic_signs", "traffic_lights"};
// Speed above which a box is moving (convert_waymo_to_rds_hq.py's
// min_moving_speed): the renderer moves a moving object's points with its
// box and averages a static one's poses (utils/bbox_utils.py).
constexpr double kMovingSpeedMps = 0.2;
constexpr char kFolder[] = "rds_hq";

// ---- A ustar archive in memory ----

void PutOctal(char* field, size_t width, uint64_t value) {
  // width - 1 digits and a NUL.
  std::snprintf(field, width, "%0*llo", static_cast<int>(width - 1),
                static_cast<unsigned long long>(value));
}

std::string UstarHeader(const std::string& name, uint64_t size, char type) {
  std::string h(512, '\0');
  std::memcpy(&h[0], name.data(), std::min<size_t>(name.size(), 100));
  PutOctal(&h[100], 8, 0644);  // mode
  PutOctal(&h[108], 8, 0);     // uid
  PutOctal(&h[116], 8, 0);     // gid
  PutOctal(&h[124], 12, size);
  PutOctal(&h[136], 12, 0);  // mtime
  h[156] = type;
  std::memcpy(&h[257], "ustar", 6);  // magic with its NUL
  std::memcpy(&h[263], "00", 2);     // version
  std::memset(&h[148], ' ', 8);      // the checksum counts itself as blanks
  unsigned sum = 0;
  for (const char c : h) sum += static_cast<unsigned char>(c);
  std::snprintf(&h[148], 7, "%06o", sum);  // 6 digits, NUL, then the blank
  h[155] = ' ';
  return h;
}

class TarWriter {
 public:
  void Add(const std::string& name, const std::string& data) {
    if (name.size() > 100) {  // a pax extended header carries the path
      const std::string body = PaxRecord("path", name);
      Append(UstarHeader("PaxHeaders/" + name.substr(0, 80), body.size(), 'x'),
             body);
    }
    Append(UstarHeader(name, data.size(), '0'), data);
  }
  // The archive: the members, then two zero blocks.
  std::string Finish() {
    bytes_.append(1024, '\0');
    return std::move(bytes_);
  }

 private:
  // "<length> key=value\n", the length counting its own digits.
  static std::string PaxRecord(const std::string& key,
                               const std::string& value) {
    const size_t rest = key.size() + value.size() + 3;  // ' ', '=', '\n'
    size_t len = rest + 1;
    while (std::to_string(len).size() + rest != len)
      len = std::to_string(len).size() + rest;
    return std::to_string(len) + " " + key + "=" + value + "\n";
  }
  void Append(const std::string& header, const std::string& data) {
    bytes_ += header;
    bytes_ += data;
    bytes_.append((512 - data.size() % 512) % 512, '\0');
  }
  std::string bytes_;
};

// ---- NumPy members ----

// Row-major 4x4.
std::vector<double> RowMajor(const Rigid3d& pose) {
  const Eigen::Matrix4d m = pose.ToMatrix();
  std::vector<double> v;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) v.push_back(m(r, c));
  return v;
}

nlohmann::json MatrixJson(const Rigid3d& pose) {
  const Eigen::Matrix4d m = pose.ToMatrix();
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r)
    rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

// The renderer's object type of a nuScenes category (CLASS_COLORS,
// utils/bbox_utils.py:18-24); "" for the categories it has no type for
// (animals, barriers, cones, ...: not written).
std::string ObjectType(const std::string& category) {
  const auto starts = [&](const char* p) { return category.rfind(p, 0) == 0; };
  if (starts("human.pedestrian.")) return "Pedestrian";
  if (category == "vehicle.bicycle" || category == "vehicle.motorcycle")
    return "Cyclist";
  if (category == "vehicle.car" || starts("vehicle.emergency.")) return "Car";
  if (starts("vehicle.bus.") || category == "vehicle.truck" ||
      category == "vehicle.trailer" || category == "vehicle.construction")
    return "Truck";
  return "";
}

std::string FrameKey(int frame) {
  char key[16];
  std::snprintf(key, sizeof(key), "%06d", frame);
  return key;
}

// The fields written per clip, in Finish's order.
std::vector<std::string> Fields() {
  std::vector<std::string> f = {"pose", "pinhole_intrinsic", "lidar_raw",
                                "all_object_info"};
  for (const char* t : kMinimapTypes) f.push_back(std::string("3d_") + t);
  return f;
}

// numpy.savez bytes of the sweep (stored, through a temporary file: the
// toolkit's one npz writer).
std::string LidarNpz(const ExportSweep& sweep, const std::string& scratch) {
  const int64_t n = static_cast<int64_t>(sweep.size());
  std::vector<float> xyz;
  xyz.reserve(3 * n);
  for (int64_t i = 0; i < n; ++i)
    xyz.insert(xyz.end(), sweep.xyzi.begin() + 4 * i,
               sweep.xyzi.begin() + 4 * i + 3);
  const std::vector<double> pose = RowMajor(sweep.world_from_sensor);
  WriteNpz(scratch,
           {{"xyz", NpyArray::Float32({n, 3}, xyz.data())},
            {"lidar_to_world", NpyArray::Float64({4, 4}, pose.data())}},
           /*compress=*/false);
  const std::vector<uint8_t> bytes = ReadFileBytes(scratch);
  fs::remove(scratch);
  return std::string(bytes.begin(), bytes.end());
}

class RdsHqExporter : public Exporter {
 public:
  explicit RdsHqExporter(const ExportOptions& options) : options_(options) {}

  ExportFormat Format() const override { return ExportFormat::kRdsHq; }

  ExportRequirements Requirements() const override {
    ExportRequirements req;
    req.min_frames = kChunkFrames;
    req.width = kWidth;
    req.height = kHeight;
    req.fps = kPoseFps;
    req.frames = false;  // poses, intrinsics, LiDAR and boxes only
    req.lidar_frame_step = kLidarStep;
    req.objects = true;
    return req;
  }

  void CheckClip(const std::string& clip_id, int num_frames) const override {
    GEODRIVE_CHECK_INPUT(
        !clip_id.empty() && clip_id.find('.') == std::string::npos &&
            clip_id.find('/') == std::string::npos,
        clip_id,
        ": rds-hq needs a clip id without '.' or '/' (webdataset "
        "splits a tar member name <clip>.<key> at its first dot)");
    GEODRIVE_CHECK_INPUT(num_frames >= kChunkFrames, clip_id, ": rds-hq needs ",
                         kChunkFrames, " frames at 30 Hz; this clip has ",
                         num_frames);
  }

  void WriteClip(const ExportClip& clip,
                 const std::string& pair_dir,
                 PairMeta* meta) const override {
    WriteSample({{kCamera, &clip}}, pair_dir, meta);
  }

  bool WritesRigs() const override { return true; }
  void WriteRig(const std::vector<ExportClip>& views,
                const std::string& pair_dir,
                PairMeta* meta) const override;

  int Finish(const std::string& out) const override;

 private:
  // One camera of a sample: its name in the config, and its view.
  struct Camera {
    std::string name;
    const ExportClip* clip = nullptr;
  };
  // The clip's tars: every camera's poses and intrinsics; the LiDAR and
  // objects of the first (the reference camera).
  void WriteSample(const std::vector<Camera>& cameras,
                   const std::string& pair_dir,
                   PairMeta* meta) const;

  ExportOptions options_;
};

void RdsHqExporter::WriteRig(const std::vector<ExportClip>& views,
                             const std::string& pair_dir,
                             PairMeta* meta) const {
  GEODRIVE_CHECK_INPUT(!views.empty(), "rds-hq: a rig with no camera");
  std::vector<Camera> cameras;
  std::set<std::string> channels;
  std::string have;
  for (const ExportClip& v : views) {
    have += (have.empty() ? "" : ",") + v.channel;
    channels.insert(v.channel);
    for (const auto& [channel, name] : kRigCameras)
      if (v.channel == channel) cameras.push_back({name, &v});
  }
  std::string need;
  for (const auto& [channel, name] : kRigCameras)
    need += (need.empty() ? "" : ",") + std::string(channel);
  GEODRIVE_CHECK_INPUT(cameras.size() == std::size(kRigCameras) &&
                           channels.size() == views.size() &&
                           views.size() == std::size(kRigCameras),
                       views.front().clip_id,
                       ": rds-hq's six-camera layout (the rds_hq_mv config) "
                       "needs the six nuScenes cameras ",
                       need, "; this rig has ", have);
  WriteSample(cameras, pair_dir, meta);
}

void RdsHqExporter::WriteSample(const std::vector<Camera>& cameras,
                                const std::string& pair_dir,
                                PairMeta* meta) const {
  const ExportClip& clip = *cameras.front().clip;
  const int n = static_cast<int>(clip.world_from_cam.size());
  CheckClip(clip.clip_id, n);
  GEODRIVE_CHECK_INPUT(
      clip.lidar && clip.objects && static_cast<int>(clip.objects->size()) == n,
      clip.clip_id, ": rds-hq needs the clip's LiDAR and objects");
  for (const Camera& c : cameras) {
    const ExportClip& v = *c.clip;
    GEODRIVE_CHECK_INPUT(
        v.camera.width == kWidth && v.camera.height == kHeight, clip.clip_id,
        ": rds-hq needs the camera at ", kWidth, "x", kHeight, ", got ",
        v.camera.width, "x", v.camera.height, " (", c.name, ")");
    GEODRIVE_CHECK_INPUT(static_cast<int>(v.world_from_cam.size()) == n,
                         clip.clip_id, ": rds-hq needs ", n, " poses of ",
                         c.name, ", got ", v.world_from_cam.size());
  }
  const std::string& id = clip.clip_id;
  const std::string dir = pair_dir + "/" + kFolder;
  for (const std::string& f : Fields()) fs::create_directories(dir + "/" + f);
  const auto write = [&](const std::string& field, TarWriter* tar) {
    WriteFileAtomic(dir + "/" + field + "/" + id + ".tar", tar->Finish());
  };
  {
    TarWriter tar;
    for (const Camera& c : cameras) {
      const std::string cam = ".pose." + c.name + ".npy";
      for (int i = 0; i < n; ++i) {
        const std::vector<double> m = RowMajor(c.clip->world_from_cam[i]);
        const std::string name = id + "." + FrameKey(i) + cam;
        tar.Add(name, SerializeNpy(name, NpyArray::Float64({4, 4}, m.data())));
      }
    }
    write("pose", &tar);
  }
  {
    TarWriter tar;
    for (const Camera& c : cameras) {
      const PinholeCamera& k = c.clip->camera;
      const double values[6] = {k.fx,
                                k.fy,
                                k.cx,
                                k.cy,
                                static_cast<double>(kWidth),
                                static_cast<double>(kHeight)};
      const std::string name = id + ".pinhole_intrinsic." + c.name + ".npy";
      tar.Add(name, SerializeNpy(name, NpyArray::Float64({6}, values)));
    }
    write("pinhole_intrinsic", &tar);
  }
  {
    // Every multiple of 3 up to the last frame must have a key
    // (render_from_rds_hq.py:319-336).
    std::set<int> keys;
    TarWriter tar;
    const std::string scratch = dir + "/.lidar.npz";
    for (const ExportSweep& s : *clip.lidar) {
      if (s.frame % kLidarStep != 0 || s.frame >= n) continue;
      tar.Add(id + "." + FrameKey(s.frame) + ".lidar_raw.npz",
              LidarNpz(s, scratch));
      keys.insert(s.frame);
    }
    for (int f = 0; f < n; f += kLidarStep) {
      GEODRIVE_CHECK_INPUT(keys.count(f), id,
                           ": rds-hq needs a LiDAR sweep "
                           "at frame ",
                           f);
    }
    write("lidar_raw", &tar);
  }
  {
    TarWriter tar;
    for (int i = 0; i < n; ++i) {
      nlohmann::json objects = nlohmann::json::object();
      for (const ExportObject& o : (*clip.objects)[i]) {
        const std::string type = ObjectType(o.category);
        if (type.empty()) continue;
        nlohmann::json j;
        j["object_to_world"] = MatrixJson(o.world_from_box);
        j["object_lwh"] = {o.lwh.x(), o.lwh.y(), o.lwh.z()};
        j["object_is_moving"] = o.speed_mps > kMovingSpeedMps;
        j["object_type"] = type;
        objects[o.track_id] = std::move(j);
      }
      tar.Add(id + "." + FrameKey(i) + ".all_object_info.json", objects.dump());
    }
    write("all_object_info", &tar);
  }
  for (const char* type : kMinimapTypes) {
    TarWriter tar;
    tar.Add(id + "." + type + ".json", R"({"labels": []})");
    write(std::string("3d_") + type, &tar);
  }
  meta->files[kFolder] = kFolder;
}

int RdsHqExporter::Finish(const std::string& out) const {
  const std::string root = out + "/" + kFolder;
  struct Clip {
    std::string name, scene;
  };
  std::vector<Clip> clips;
  for (const std::string& name : internal::PairsWithExport(out, kFolder))
    clips.push_back({name, ReadPairMeta(out + "/pairs/" + name).scene_name});
  if (clips.empty() && !fs::exists(root)) return 0;
  for (const std::string& field : Fields()) {
    const fs::path dir = fs::path(root) / field;
    fs::create_directories(dir);
    std::vector<fs::path> old;  // links of earlier runs
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_symlink()) old.push_back(e.path());
    for (const fs::path& p : old) fs::remove(p);
    for (const Clip& c : clips) {
      const fs::path link = dir / (c.name + ".tar");
      std::error_code ec;
      fs::create_symlink(fs::path("../..") / "pairs" / c.name / kFolder /
                             field / (c.name + ".tar"),
                         link, ec);
      GEODRIVE_CHECK_INPUT(!ec, link.string(), ": cannot create link (",
                           ec.message(), ")");
    }
  }
  std::set<std::string> scenes;
  for (const Clip& c : clips) scenes.insert(c.scene);
  const std::set<std::string> val = ValScenes(scenes, options_);
  nlohmann::json lists[2] = {nlohmann::json::array(), nlohmann::json::array()};
  for (const Clip& c : clips)
    lists[val.count(c.scene) ? 1 : 0].push_back(c.name);
  WriteFileAtomic(root + "/clips_train.json", lists[0].dump(1) + "\n");
  WriteFileAtomic(root + "/clips_val.json", lists[1].dump(1) + "\n");
  return static_cast<int>(clips.size());
}

}  // namespace
}  // namespace rds_hq_export

std::unique_ptr<Exporter> CreateRdsHqExporter(const ExportOptions& options) {
  return std::make_unique<rds_hq_export::RdsHqExporter>(options);
}

}  // namespace internal
}  // namespace geodrive
