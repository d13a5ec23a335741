// The drivestudio export (dataset/exporter.h): drivestudio's nuScenes layout
// as its loader reads it (ziyc/drivestudio, datasets/nuscenes/
// nuscenes_sourceloader.py, datasets/base/pixel_source.py), as
// docs/reference/trainer-formats.md §4 cites it ("DS" there). One scene per
// clip, PAIR/drivestudio/ (linked as OUT/drivestudio/%03d, the clips in name
// order, OUT/drivestudio/scenes.json mapping "%03d" to the clip id):
//
//   images/%03d_0.jpg        the camera frames at 1600x900 (RGB JPEG; the
//                            source JPEG's bytes when it is 1600x900)
//   extrinsics/%03d_0.txt    4x4 world_from_cam, OpenCV axes, per frame
//                            (nuscenes_sourceloader.py:102-111)
//   intrinsics/0.txt         fx fy cx cy k1 k2 p1 p2 k3 at 1600x900, no
//                            distortion (nuscenes_sourceloader.py:82-99)
//   lidar_pose/%03d.txt      4x4 world_from_lidar; their count is the frame
//                            count (:359-377)
//   lidar/%03d.bin           float32 x, y, z, intensity in the LiDAR's frame,
//                            the sweep nearest the frame (:392-406)
//   sky_masks/%03d_0.png     1-bit gray (0/255 read as "L"): a pixel whose
//                            ray points above the horizon, within the
//                            LiDAR's vertical field of view, above every
//                            LiDAR return of the frame and point of the
//                            clip's scene in its column (SkyMask)
//   dynamic_masks/{all,human,vehicle}/%03d_0.png
//                            1-bit gray: the axis-aligned 2D box of each
//                            projected 3D box wholly in front (z > 0.1) and
//                            inside the image, as
//                            nuscenes_preprocess.py:633-687 draws it
//   instances/instances_info.json, frame_instances.json
//                            the boxes of the 18 categories drivestudio models
//                            (OBJECT_CLASS_NODE_MAPPING, :21-45), ids
//                            "0".."N-1"
//
// Every pose is in the pair's frame (camera 0 at frame 0), which makes the
// loader's re-basing on extrinsics/000_0.txt the identity. Only CAM_FRONT is
// written, as camera 0 (drivestudio's order puts it first): train with
// dataset=nuscenes/1cams.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iterator>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>

#include "dataset/exporter.h"
#include "dataset/internal/exporters.h"
#include "dataset/internal/pair_png.h"
#include "dataset/pairs.h"
#include "geometry/image_io.h"
#include "geometry/point_cloud.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace internal {
// Named: a unity build puts the exporters' files in one translation unit.
namespace drivestudio_export {
namespace {

namespace fs = std::filesystem;
using ojson = nlohmann::ordered_json;

constexpr int kWidth = 1600, kHeight = 900;  // dataset_meta.py:98-128
constexpr int kCamera = 0;  // a single camera: CAM_FRONT in drivestudio's order
// drivestudio's camera order of nuScenes (datasets/dataset_meta.py:98-128):
// a rig's channels are numbered by it.
constexpr const char* kCameraOrder[] = {"CAM_FRONT",       "CAM_FRONT_LEFT",
                                        "CAM_FRONT_RIGHT", "CAM_BACK_LEFT",
                                        "CAM_BACK_RIGHT",  "CAM_BACK"};
constexpr int kJpegQuality = 95;
constexpr char kFolder[] = "drivestudio";

// nuscenes_preprocess.py:46-70: the non-rigid ("human" masks) and rigid
// ("vehicle" masks) dynamic classes; together the 18 keys of
// OBJECT_CLASS_NODE_MAPPING (nuscenes_sourceloader.py:21-45).
constexpr const char* kNonRigid[] = {"animal",
                                     "human.pedestrian.adult",
                                     "human.pedestrian.child",
                                     "human.pedestrian.construction_worker",
                                     "human.pedestrian.personal_mobility",
                                     "human.pedestrian.police_officer",
                                     "human.pedestrian.stroller",
                                     "human.pedestrian.wheelchair",
                                     "vehicle.bicycle",
                                     "vehicle.motorcycle"};
constexpr const char* kRigid[] = {"vehicle.bus.bendy",
                                  "vehicle.bus.rigid",
                                  "vehicle.car",
                                  "vehicle.construction",
                                  "vehicle.emergency.ambulance",
                                  "vehicle.emergency.police",
                                  "vehicle.trailer",
                                  "vehicle.truck"};

template <size_t N>
bool In(const char* const (&list)[N], const std::string& category) {
  return std::find(std::begin(list), std::end(list), category) !=
         std::end(list);
}

std::string Frame(int t) {
  char name[16];
  std::snprintf(name, sizeof(name), "%03d", t);
  return name;
}

// 4 rows of 4 numbers (np.loadtxt reads it as (4,4)).
std::string MatrixText(const Rigid3d& pose) {
  const Eigen::Matrix4d m = pose.ToMatrix();
  std::string text;
  char v[32];
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      std::snprintf(v, sizeof(v), "%.17g", m(r, c));
      text += std::string(c ? " " : "") + v;
    }
    text += "\n";
  }
  return text;
}

// The image area one LiDAR return or scene point stands for: +-0.5 degrees
// of azimuth (spinning LiDARs step 0.1-0.5 degrees) and 1.5 degrees above it
// (a ring's spacing: 1.33 degrees for nuScenes' 32 rings), so that what lies
// between the highest ring that hits and the next is not called sky.
constexpr double kReturnHalfWidthRad = 0.5 * M_PI / 180;
constexpr double kReturnRiseRad = 1.5 * M_PI / 180;

// Lowers top[x] to the row of each point of `xyz` (`stride` floats a point,
// x, y, z first) in `cam_from_points`' camera that lands in column x: the
// highest point of every column, before the +-0.5 degree widening.
void LowerColumnTops(const float* xyz,
                     size_t count,
                     size_t stride,
                     const Rigid3d& cam_from_points,
                     const PinholeCamera& cam,
                     int width,
                     int height,
                     std::vector<int>* top) {
  const Eigen::Matrix3f r =
      cam_from_points.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f t = cam_from_points.translation.cast<float>();
  const float fx = static_cast<float>(cam.fx), cx = static_cast<float>(cam.cx);
  const float fy = static_cast<float>(cam.fy), cy = static_cast<float>(cam.cy);
  for (size_t i = 0; i < count; ++i) {
    const Eigen::Vector3f c =
        r * Eigen::Map<const Eigen::Vector3f>(xyz + i * stride) + t;
    if (!(c.z() > 0.1f)) continue;
    const float u = fx * c.x() / c.z() + cx;
    const float v = fy * c.y() / c.z() + cy;
    if (!(u >= 0 && u < width && v < height)) continue;
    const int ui = static_cast<int>(u);
    const int vi = v < 0 ? -1 : static_cast<int>(v);
    (*top)[ui] = std::min((*top)[ui], vi);
  }
}

// Sky: the pixel's ray points above the horizon (a positive component along
// the world's up), within the LiDAR's vertical field of view (no higher than
// its highest return of the sweep, seen from the sensor), and above
// everything in its column: every return of the frame's sweep and every point
// of the clip's scene (`scene`, in world_from_cam's frame), each standing for
// +-0.5 degrees of azimuth and 1.5 degrees up. What lies above the LiDAR's
// reach is not called sky (unknown).
cv::Mat SkyMask(const PinholeCamera& cam,
                const Rigid3d& world_from_cam,
                const Eigen::Vector3d& world_up,
                const PointCloud* scene,
                const ExportSweep& sweep,
                int w,
                int h) {
  const Rigid3d cam_from_world = world_from_cam.Inverse();
  const Rigid3d cam_from_sensor = cam_from_world * sweep.world_from_sensor;
  std::vector<int> column(w, h);  // the highest point of each column
  LowerColumnTops(sweep.xyzi.data(), sweep.size(), 4, cam_from_sensor, cam, w,
                  h, &column);
  if (scene != nullptr && !scene->empty()) {
    LowerColumnTops(scene->positions.front().data(), scene->size(),
                    sizeof(Eigen::Vector3f) / sizeof(float), cam_from_world,
                    cam, w, h, &column);
  }
  const int half_px =
      static_cast<int>(std::ceil(cam.fx * std::tan(kReturnHalfWidthRad)));
  const int rise_px =
      static_cast<int>(std::ceil(cam.fy * std::tan(kReturnRiseRad)));
  std::vector<int> top(w, h);  // column tops widened by +-half_px, raised
  for (int x = 0; x < w; ++x) {
    for (int k = std::max(0, x - half_px); k <= std::min(w - 1, x + half_px);
         ++k) {
      if (column[k] < h) top[x] = std::min(top[x], column[k] - rise_px);
    }
  }
  // The sweep's highest return seen from the sensor, as the tangent of its
  // elevation, z / |xy| (monotonic in the elevation; a return straight up
  // counts as the largest finite tangent). A direction d lies no higher
  // <=> d.z <= tan_max |d.xy|.
  double tan_max = -std::numeric_limits<double>::max();
  for (size_t i = 0; i < sweep.size(); ++i) {
    const float* p = &sweep.xyzi[4 * i];
    const double xy = std::sqrt(static_cast<double>(p[0]) * p[0] +
                                static_cast<double>(p[1]) * p[1]);
    const double tan = xy > 0
                           ? p[2] / xy
                           : std::copysign(std::numeric_limits<double>::max(),
                                           static_cast<double>(p[2]));
    tan_max = std::max(tan_max, tan);
  }
  const Eigen::Vector3d up = world_from_cam.rotation.inverse() * world_up;
  const Eigen::Matrix3d sensor_from_cam =
      cam_from_sensor.rotation.inverse().toRotationMatrix();
  // Along a row, the ray (x - cx) / fx, (y - cy) / fy, 1 and its sensor-frame
  // direction d change linearly with x.
  const Eigen::Vector3d ray_dx(1.0 / cam.fx, 0, 0);
  const Eigen::Vector3d d_dx = sensor_from_cam * ray_dx;
  const double up_dx = ray_dx.dot(up);
  cv::Mat sky(h, w, CV_8U, cv::Scalar(0));
  for (int y = 0; y < h; ++y) {
    uint8_t* row = sky.ptr<uint8_t>(y);
    const Eigen::Vector3d ray0(-cam.cx / cam.fx, (y - cam.cy) / cam.fy, 1.0);
    const Eigen::Vector3d d0 = sensor_from_cam * ray0;
    const double up0 = ray0.dot(up);
    for (int x = 0; x < w; ++x) {
      if (y >= top[x] || !(up0 + x * up_dx > 0)) continue;
      const Eigen::Vector3d d = d0 + x * d_dx;
      if (d.z() > tan_max * std::sqrt(d.x() * d.x() + d.y() * d.y())) continue;
      row[x] = 255;
    }
  }
  return sky;
}

// The box's axis-aligned 2D box, as upstream draws it: all eight corners at
// z > 0.1 and inside [0, W) x [0, H), else nothing; pixel bounds truncated to
// integers, the maxima exclusive. Returns true when it drew.
bool DrawBox(const ExportObject& o,
             const PinholeCamera& cam,
             const Rigid3d& cam_from_world,
             cv::Mat* mask) {
  int umin = kWidth, umax = -1, vmin = kHeight, vmax = -1;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d corner(((k & 1) ? 0.5 : -0.5) * o.lwh.x(),
                                 ((k & 2) ? 0.5 : -0.5) * o.lwh.y(),
                                 ((k & 4) ? 0.5 : -0.5) * o.lwh.z());
    const Eigen::Vector3d c = cam_from_world * (o.world_from_box * corner);
    if (!(c.z() > 0.1)) return false;
    const double u = cam.fx * c.x() / c.z() + cam.cx;
    const double v = cam.fy * c.y() / c.z() + cam.cy;
    if (!(u >= 0 && u < mask->cols && v >= 0 && v < mask->rows)) return false;
    umin = std::min(umin, static_cast<int>(u));
    umax = std::max(umax, static_cast<int>(u));
    vmin = std::min(vmin, static_cast<int>(v));
    vmax = std::max(vmax, static_cast<int>(v));
  }
  if (umax == umin || vmax == vmin) return false;
  (*mask)(cv::Rect(umin, vmin, umax - umin, vmax - vmin)).setTo(255);
  return true;
}

// 1-bit PNG bytes of the clip's masks (WriteMaskPng's), an empty mask
// encoded once: most frames' masks of a kind are empty.
class MaskEncoder {
 public:
  explicit MaskEncoder(std::string what) : what_(std::move(what)) {}
  // The PNG of `mask`; `any` = it has a pixel set.
  std::string Encode(const cv::Mat& mask, bool any) {
    if (any) return EncodeMaskPng(what_, mask);
    if (empty_.empty() || empty_size_ != mask.size()) {
      empty_ = EncodeMaskPng(what_, mask);
      empty_size_ = mask.size();
    }
    return empty_;
  }

 private:
  std::string what_;
  std::string empty_;
  cv::Size empty_size_;
};

// instances_info.json and frame_instances.json: the boxes of the 18
// categories, numbered in order of first appearance.
void WriteInstances(const std::string& dir, const ExportClip& clip) {
  ojson info = ojson::object(), frames = ojson::object();
  std::map<std::string, int> ids;
  for (size_t t = 0; t < clip.objects->size(); ++t) {
    ojson& in_frame = frames[std::to_string(t)] = ojson::array();
    for (const ExportObject& o : (*clip.objects)[t]) {
      if (!In(kNonRigid, o.category) && !In(kRigid, o.category)) continue;
      const auto [it, added] =
          ids.emplace(o.track_id, static_cast<int>(ids.size()));
      ojson& inst = info[std::to_string(it->second)];
      if (added) {
        inst["id"] = o.track_id;
        inst["class_name"] = o.category;
        inst["frame_annotations"] = {{"frame_idx", ojson::array()},
                                     {"obj_to_world", ojson::array()},
                                     {"box_size", ojson::array()}};
      }
      const Eigen::Matrix4d m = o.world_from_box.ToMatrix();
      ojson rows = ojson::array();
      for (int r = 0; r < 4; ++r)
        rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
      ojson& fa = inst["frame_annotations"];
      fa["frame_idx"].push_back(t);
      fa["obj_to_world"].push_back(std::move(rows));
      fa["box_size"].push_back({o.lwh.x(), o.lwh.y(), o.lwh.z()});
      in_frame.push_back(it->second);
    }
  }
  WriteFileAtomic(dir + "/instances_info.json", info.dump() + "\n");
  WriteFileAtomic(dir + "/frame_instances.json", frames.dump() + "\n");
}

// Frame t's image as a JPEG: the source file's bytes when the frame is the
// source image unchanged and that is a JPEG stored upright (no second lossy
// encode, and no CPU), else encoded at quality 95.
void WriteImage(const std::string& path, const ExportClip& clip, int t) {
  if (clip.images_are_source && static_cast<int>(clip.image_paths.size()) > t) {
    const ImageFile file = ReadImageFile(clip.image_paths[t]);
    const ImageHeader header = ReadImageHeader(file);
    if (header.jpeg && header.orientation == 1 &&
        header.size == cv::Size(kWidth, kHeight)) {
      WriteFileAtomic(path, file.bytes.data(), file.bytes.size());
      return;
    }
  }
  WriteJpeg(path, (*clip.images)[t], kJpegQuality);
}

// The LiDAR sweep as float32 (N,4) x, y, z, intensity.
void WriteLidar(const std::string& path, const ExportSweep& sweep) {
  WriteFileAtomic(path, sweep.xyzi.data(), sweep.xyzi.size() * sizeof(float));
}

class DrivestudioExporter : public Exporter {
 public:
  ExportFormat Format() const override { return ExportFormat::kDrivestudio; }

  ExportRequirements Requirements() const override {
    ExportRequirements req;
    req.width = kWidth;
    req.height = kHeight;
    req.condition = false;  // no condition: the sky rule projects the scene
    req.lidar_frame_step = 1;
    req.objects = true;
    return req;
  }

  void WriteClip(const ExportClip& clip,
                 const std::string& pair_dir,
                 PairMeta* meta) const override;

  bool WritesRigs() const override { return true; }
  void WriteRig(const std::vector<ExportClip>& views,
                const std::string& pair_dir,
                PairMeta* meta) const override;

  int Finish(const std::string& out) const override;
};

// drivestudio's camera index of a nuScenes channel (dataset_meta.py:98-128);
// -1 for another name.
int CameraIndex(const std::string& channel) {
  for (int i = 0; i < static_cast<int>(std::size(kCameraOrder)); ++i)
    if (channel == kCameraOrder[i]) return i;
  return -1;
}

// Checks one camera's clip of `n` frames: poses, sweeps and objects for
// every frame, frames at 1600x900.
void CheckCameraClip(const ExportClip& clip, int n) {
  GEODRIVE_CHECK_INPUT(
      clip.lidar && clip.objects && clip.images &&
          static_cast<int>(clip.images->size()) == n &&
          static_cast<int>(clip.lidar->size()) == n &&
          static_cast<int>(clip.objects->size()) == n &&
          static_cast<int>(clip.world_from_cam.size()) == n,
      clip.clip_id,
      ": drivestudio needs a frame, a pose, a LiDAR sweep and the objects of "
      "every frame (",
      n, " frames)");
  for (const cv::Mat& image : *clip.images) {
    GEODRIVE_CHECK_INPUT(image.size() == cv::Size(kWidth, kHeight),
                         clip.clip_id, ": drivestudio needs frames at ", kWidth,
                         "x", kHeight, ", got ", image.cols, "x", image.rows);
  }
}

// What the cameras share: lidar/, lidar_pose/ and instances/.
void WriteSceneFiles(const std::string& dir, const ExportClip& clip) {
  for (size_t t = 0; t < clip.lidar->size(); ++t) {
    const ExportSweep& sweep = (*clip.lidar)[t];
    const std::string name = Frame(static_cast<int>(t));
    WriteFileAtomic(dir + "/lidar_pose/" + name + ".txt",
                    MatrixText(sweep.world_from_sensor));
    WriteLidar(dir + "/lidar/" + name + ".bin", sweep);
  }
  WriteInstances(dir + "/instances", clip);
}

// Camera `cam_index`'s files: intrinsics/, and per frame images/,
// extrinsics/, sky_masks/ and dynamic_masks/.
void WriteCameraFiles(const std::string& dir,
                      const ExportClip& clip,
                      int cam_index) {
  const PinholeCamera& cam = clip.camera;
  char k[256];
  std::snprintf(k, sizeof(k), "%.17g\n%.17g\n%.17g\n%.17g\n0\n0\n0\n0\n0\n",
                cam.fx, cam.fy, cam.cx, cam.cy);
  const std::string cam_id = std::to_string(cam_index);
  WriteFileAtomic(dir + "/intrinsics/" + cam_id + ".txt", k);
  MaskEncoder masks(clip.clip_id + ": drivestudio mask");
  for (size_t t = 0; t < clip.images->size(); ++t) {
    const std::string name = Frame(static_cast<int>(t)) + "_" + cam_id;
    WriteImage(dir + "/images/" + name + ".jpg", clip, static_cast<int>(t));
    WriteFileAtomic(dir + "/extrinsics/" + name + ".txt",
                    MatrixText(clip.world_from_cam[t]));
    const cv::Mat sky =
        SkyMask(cam, clip.world_from_cam[t], clip.world_up, clip.scene_cloud,
                (*clip.lidar)[t], kWidth, kHeight);
    WriteFileAtomic(dir + "/sky_masks/" + name + ".png",
                    masks.Encode(sky, cv::countNonZero(sky) > 0));
    const Rigid3d cam_from_world = clip.world_from_cam[t].Inverse();
    cv::Mat human(kHeight, kWidth, CV_8U, cv::Scalar(0));
    cv::Mat vehicle = human.clone();
    bool any_human = false, any_vehicle = false;
    for (const ExportObject& o : (*clip.objects)[t]) {
      if (In(kNonRigid, o.category))
        any_human |= DrawBox(o, cam, cam_from_world, &human);
      if (In(kRigid, o.category))
        any_vehicle |= DrawBox(o, cam, cam_from_world, &vehicle);
    }
    const std::string dyn = dir + "/dynamic_masks/";
    const std::string human_png = masks.Encode(human, any_human);
    const std::string vehicle_png = masks.Encode(vehicle, any_vehicle);
    // all = human | vehicle: one of them when the other is empty.
    WriteFileAtomic(dyn + "all/" + name + ".png",
                    !any_human     ? vehicle_png
                    : !any_vehicle ? human_png
                                   : masks.Encode(human | vehicle, true));
    WriteFileAtomic(dyn + "human/" + name + ".png", human_png);
    WriteFileAtomic(dyn + "vehicle/" + name + ".png", vehicle_png);
  }
}

std::string MakeSceneFolder(const std::string& pair_dir) {
  const std::string dir = pair_dir + "/" + kFolder;
  for (const char* sub :
       {"images", "extrinsics", "intrinsics", "lidar_pose", "lidar",
        "sky_masks", "dynamic_masks/all", "dynamic_masks/human",
        "dynamic_masks/vehicle", "instances"})
    fs::create_directories(dir + "/" + sub);
  return dir;
}

void DrivestudioExporter::WriteClip(const ExportClip& clip,
                                    const std::string& pair_dir,
                                    PairMeta* meta) const {
  const int n = static_cast<int>(clip.images->size());
  CheckClip(clip.clip_id, n);
  CheckCameraClip(clip, n);
  const std::string dir = MakeSceneFolder(pair_dir);
  WriteSceneFiles(dir, clip);
  WriteCameraFiles(dir, clip, kCamera);
  meta->files[kFolder] = kFolder;
}

void DrivestudioExporter::WriteRig(const std::vector<ExportClip>& views,
                                   const std::string& pair_dir,
                                   PairMeta* meta) const {
  GEODRIVE_CHECK_INPUT(!views.empty(), pair_dir, ": a rig with no camera");
  const ExportClip& reference = views.front();
  const int n = static_cast<int>(reference.images->size());
  CheckClip(reference.clip_id, n);
  std::vector<int> index;
  for (const ExportClip& v : views) {
    CheckCameraClip(v, n);
    index.push_back(CameraIndex(v.channel));
    GEODRIVE_CHECK_INPUT(index.back() >= 0, v.clip_id,
                         ": drivestudio's nuScenes layout numbers the cameras "
                         "CAM_FRONT, CAM_FRONT_LEFT, CAM_FRONT_RIGHT, "
                         "CAM_BACK_LEFT, CAM_BACK_RIGHT, CAM_BACK; ",
                         v.channel, " is none of them");
  }
  const std::string dir = MakeSceneFolder(pair_dir);
  WriteSceneFiles(dir, reference);
  for (size_t k = 0; k < views.size(); ++k)
    WriteCameraFiles(dir, views[k], index[k]);
  meta->files[kFolder] = kFolder;
}

int DrivestudioExporter::Finish(const std::string& out) const {
  const std::string root = out + "/" + kFolder;
  const std::vector<std::string> clips =
      internal::PairsWithExport(out, kFolder);
  if (clips.empty() && !fs::exists(root)) return 0;
  fs::create_directories(root);
  std::vector<fs::path> old;  // scene links of earlier runs
  for (const auto& e : fs::directory_iterator(root))
    if (e.is_symlink()) old.push_back(e.path());
  for (const fs::path& p : old) fs::remove(p);
  ojson scenes = ojson::object();
  for (size_t i = 0; i < clips.size(); ++i) {
    const std::string idx = Frame(static_cast<int>(i));
    const fs::path link = fs::path(root) / idx;
    std::error_code ec;
    fs::create_directory_symlink(fs::path("..") / "pairs" / clips[i] / kFolder,
                                 link, ec);
    GEODRIVE_CHECK_INPUT(!ec, link.string(), ": cannot create link (",
                         ec.message(), ")");
    scenes[idx] = clips[i];
  }
  WriteFileAtomic(root + "/scenes.json", scenes.dump(1) + "\n");
  return static_cast<int>(clips.size());
}

}  // namespace
}  // namespace drivestudio_export

std::unique_ptr<Exporter> CreateDrivestudioExporter(
    const ExportOptions& options) {
  (void)options;  // no split: drivestudio has no train/val lists
  return std::make_unique<drivestudio_export::DrivestudioExporter>();
}

}  // namespace internal
}  // namespace geodrive
