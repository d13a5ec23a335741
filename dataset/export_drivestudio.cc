// The drivestudio export (dataset/exporter.h): drivestudio's nuScenes layout
// as its loader reads it (ziyc/drivestudio, datasets/nuscenes/
// nuscenes_sourceloader.py, datasets/base/pixel_source.py), as
// docs/reference/trainer-formats.md §4 cites it ("DS" there). One scene per
// clip, PAIR/drivestudio/ (linked as OUT/drivestudio/%03d, the clips in name
// order, OUT/drivestudio/scenes.json mapping "%03d" to the clip id):
//
//   images/%03d_0.jpg        the camera frames at 1600x900 (RGB JPEG)
//   extrinsics/%03d_0.txt    4x4 world_from_cam, OpenCV axes, per frame
//                            (nuscenes_sourceloader.py:102-111)
//   intrinsics/0.txt         fx fy cx cy k1 k2 p1 p2 k3 at 1600x900, no
//                            distortion (nuscenes_sourceloader.py:82-99)
//   lidar_pose/%03d.txt      4x4 world_from_lidar; their count is the frame
//                            count (:359-377)
//   lidar/%03d.bin           float32 x, y, z, intensity in the LiDAR's frame,
//                            the sweep nearest the frame (:392-406)
//   sky_masks/%03d_0.png     0/255: a pixel whose ray points above the
//                            horizon, within the LiDAR's vertical field of
//                            view, above every LiDAR return of the frame and
//                            condition point drawn in its column (SkyMask)
//   dynamic_masks/{all,human,vehicle}/%03d_0.png
//                            0/255: the axis-aligned 2D box of each projected
//                            3D box wholly in front (z > 0.1) and inside the
//                            image, as nuscenes_preprocess.py:633-687 draws it
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
#include <map>
#include <nlohmann/json.hpp>

#include "dataset/exporter.h"
#include "dataset/internal/exporters.h"
#include "dataset/internal/pair_png.h"
#include "dataset/pairs.h"
#include "geometry/image_io.h"
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
constexpr int kCamera = 0;                   // CAM_FRONT in drivestudio's order
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

// The image area one LiDAR return stands for: +-0.5 degrees of azimuth
// (spinning LiDARs step 0.1-0.5 degrees) and 1.5 degrees above it (a ring's
// spacing: 1.33 degrees for nuScenes' 32 rings), so that what lies between
// the highest ring that hits and the next is not called sky.
constexpr double kReturnHalfWidthRad = 0.5 * M_PI / 180;
constexpr double kReturnRiseRad = 1.5 * M_PI / 180;

// Sky: the pixel's ray points above the horizon (a positive component along
// the world's up), within the LiDAR's vertical field of view (no higher than
// its highest return of the sweep, seen from the sensor), and above
// everything in its column: every return of the frame's sweep (each standing
// for +-0.5 degrees of azimuth and 1.5 degrees up) and every condition point
// drawn. What lies
// above the LiDAR's reach is not called sky (unknown).
cv::Mat SkyMask(const PinholeCamera& cam,
                const Rigid3d& world_from_cam,
                const Eigen::Vector3d& world_up,
                const cv::Mat& drawn,
                const ExportSweep& sweep) {
  const int w = drawn.cols, h = drawn.rows;
  std::vector<int> top(w, h);
  for (int x = 0; x < w; ++x) {  // the highest drawn pixel of each column
    int y = 0;
    while (y < h && drawn.at<uint8_t>(y, x) == 0) ++y;
    top[x] = y;
  }
  const Rigid3d cam_from_sensor =
      world_from_cam.Inverse() * sweep.world_from_sensor;
  const int half_px =
      static_cast<int>(std::ceil(cam.fx * std::tan(kReturnHalfWidthRad)));
  const int rise_px =
      static_cast<int>(std::ceil(cam.fy * std::tan(kReturnRiseRad)));
  double max_elevation = -M_PI / 2;
  for (size_t i = 0; i < sweep.size(); ++i) {
    const float* p = &sweep.xyzi[4 * i];
    const Eigen::Vector3d s(p[0], p[1], p[2]);
    max_elevation =
        std::max(max_elevation, std::atan2(s.z(), std::hypot(s.x(), s.y())));
    const Eigen::Vector3d c = cam_from_sensor * s;
    if (!(c.z() > 0.1)) continue;
    const double u = cam.fx * c.x() / c.z() + cam.cx;
    const double v = cam.fy * c.y() / c.z() + cam.cy;
    if (!(u >= 0 && u < w && v >= 0 && v < h)) continue;
    const int ui = static_cast<int>(u), vi = static_cast<int>(v) - rise_px;
    for (int x = std::max(0, ui - half_px); x <= std::min(w - 1, ui + half_px);
         ++x)
      top[x] = std::min(top[x], vi);
  }
  const Eigen::Vector3d up = world_from_cam.rotation.inverse() * world_up;
  const Eigen::Matrix3d sensor_from_cam =
      cam_from_sensor.rotation.inverse().toRotationMatrix();
  cv::Mat sky(drawn.size(), CV_8U, cv::Scalar(0));
  for (int x = 0; x < w; ++x) {
    for (int y = 0; y < top[x]; ++y) {
      const Eigen::Vector3d ray((x - cam.cx) / cam.fx, (y - cam.cy) / cam.fy,
                                1.0);
      if (!(ray.dot(up) > 0)) continue;
      const Eigen::Vector3d d = sensor_from_cam * ray;
      if (std::atan2(d.z(), std::hypot(d.x(), d.y())) > max_elevation) continue;
      sky.at<uint8_t>(y, x) = 255;
    }
  }
  return sky;
}

// The box's axis-aligned 2D box, as upstream draws it: all eight corners at
// z > 0.1 and inside [0, W) x [0, H), else nothing; pixel bounds truncated to
// integers, the maxima exclusive.
void DrawBox(const ExportObject& o,
             const PinholeCamera& cam,
             const Rigid3d& cam_from_world,
             cv::Mat* mask) {
  int umin = kWidth, umax = -1, vmin = kHeight, vmax = -1;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d corner(((k & 1) ? 0.5 : -0.5) * o.lwh.x(),
                                 ((k & 2) ? 0.5 : -0.5) * o.lwh.y(),
                                 ((k & 4) ? 0.5 : -0.5) * o.lwh.z());
    const Eigen::Vector3d c = cam_from_world * (o.world_from_box * corner);
    if (!(c.z() > 0.1)) return;
    const double u = cam.fx * c.x() / c.z() + cam.cx;
    const double v = cam.fy * c.y() / c.z() + cam.cy;
    if (!(u >= 0 && u < mask->cols && v >= 0 && v < mask->rows)) return;
    umin = std::min(umin, static_cast<int>(u));
    umax = std::max(umax, static_cast<int>(u));
    vmin = std::min(vmin, static_cast<int>(v));
    vmax = std::max(vmax, static_cast<int>(v));
  }
  if (umax == umin || vmax == vmin) return;
  (*mask)(cv::Rect(umin, vmin, umax - umin, vmax - vmin)).setTo(255);
}

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
    req.depth = true;  // the drawn masks, for the sky masks
    req.lidar_frame_step = 1;
    req.objects = true;
    return req;
  }

  void WriteClip(const ExportClip& clip,
                 const std::string& pair_dir,
                 PairMeta* meta) const override;

  int Finish(const std::string& out) const override;
};

void DrivestudioExporter::WriteClip(const ExportClip& clip,
                                    const std::string& pair_dir,
                                    PairMeta* meta) const {
  const int n = static_cast<int>(clip.images->size());
  CheckClip(clip.clip_id, n);
  GEODRIVE_CHECK_INPUT(
      clip.lidar && clip.objects && clip.drawn &&
          static_cast<int>(clip.lidar->size()) == n &&
          static_cast<int>(clip.objects->size()) == n &&
          static_cast<int>(clip.world_from_cam.size()) == n,
      clip.clip_id,
      ": drivestudio needs a pose, a LiDAR sweep, the objects and the drawn "
      "mask of every frame");
  const std::string dir = pair_dir + "/" + kFolder;
  for (const char* sub :
       {"images", "extrinsics", "intrinsics", "lidar_pose", "lidar",
        "sky_masks", "dynamic_masks/all", "dynamic_masks/human",
        "dynamic_masks/vehicle", "instances"})
    fs::create_directories(dir + "/" + sub);
  const PinholeCamera& cam = clip.camera;
  char k[256];
  std::snprintf(k, sizeof(k), "%.17g\n%.17g\n%.17g\n%.17g\n0\n0\n0\n0\n0\n",
                cam.fx, cam.fy, cam.cx, cam.cy);
  const std::string cam_id = std::to_string(kCamera);
  WriteFileAtomic(dir + "/intrinsics/" + cam_id + ".txt", k);
  for (int t = 0; t < n; ++t) {
    const cv::Mat& image = (*clip.images)[t];
    GEODRIVE_CHECK_INPUT(image.size() == cv::Size(kWidth, kHeight) &&
                             (*clip.drawn)[t].size() == image.size(),
                         clip.clip_id, ": drivestudio needs frames at ", kWidth,
                         "x", kHeight, ", got ", image.cols, "x", image.rows);
    const std::string name = Frame(t) + "_" + cam_id;
    WriteJpeg(dir + "/images/" + name + ".jpg", image, kJpegQuality);
    WriteFileAtomic(dir + "/extrinsics/" + name + ".txt",
                    MatrixText(clip.world_from_cam[t]));
    const ExportSweep& sweep = (*clip.lidar)[t];
    WriteFileAtomic(dir + "/lidar_pose/" + Frame(t) + ".txt",
                    MatrixText(sweep.world_from_sensor));
    WriteLidar(dir + "/lidar/" + Frame(t) + ".bin", sweep);
    WritePairPng(dir + "/sky_masks/" + name + ".png",
                 SkyMask(cam, clip.world_from_cam[t], clip.world_up,
                         (*clip.drawn)[t], sweep));
    const Rigid3d cam_from_world = clip.world_from_cam[t].Inverse();
    cv::Mat human(kHeight, kWidth, CV_8U, cv::Scalar(0));
    cv::Mat vehicle = human.clone();
    for (const ExportObject& o : (*clip.objects)[t]) {
      if (In(kNonRigid, o.category)) DrawBox(o, cam, cam_from_world, &human);
      if (In(kRigid, o.category)) DrawBox(o, cam, cam_from_world, &vehicle);
    }
    const std::string masks = dir + "/dynamic_masks/";
    WritePairPng(masks + "all/" + name + ".png", human | vehicle);
    WritePairPng(masks + "human/" + name + ".png", human);
    WritePairPng(masks + "vehicle/" + name + ".png", vehicle);
  }
  WriteInstances(dir + "/instances", clip);
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
