// Scene source "depth-folder": the worked example of docs/ARCHITECTURE.md
// ("a new scene source is one file plus one registration line"). Reads
//
//   DIR/depth/000000.npy   frame-0 z-depth (H, W), float32/float64
//   DIR/cameras.json       {"units": "metres",
//                           "frames": [{"fx": .., "fy": .., "cx": .., "cy": ..,
//                                       "width": W, "height": H,
//                                       "world_from_cam": [16 numbers, 4x4
//                                                          row-major]}, ...]}
//
// Frame 0's depth is unprojected with frame 0's K (integer-index pixels) in
// camera 0's frame; the trajectory is cam0_from_cam = inverse(world_from_cam0)
// * world_from_cam_i. Colours come from SceneInputs::image / image_path, else
// from the clip's frame-0 image, resized to the depth size. kPaper keeps
// depths within [min_depth_m, max_depth_m] when the units are metres.

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "dataset/scene/define.h"
#include "geometry/image_io.h"
#include "geometry/pointmap.h"
#include "geometry/util/json_fields.h"
#include "geometry/util/status.h"
#include "render/video/video.h"

namespace geodrive {
namespace {

using internal::JsonNumber;

Rigid3d ReadPose(const std::string& path,
                 const nlohmann::json& j,
                 const std::string& where) {
  if (!j.is_array() || j.size() != 16)
    ThrowInputError(path, where, " must be an array of 16 numbers (4x4)");
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i)
    m(i / 4, i % 4) =
        JsonNumber(path, j[i], where + "[" + std::to_string(i) + "]");
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-5 ||
      r.determinant() < 0 || m.row(3) != Eigen::RowVector4d(0, 0, 0, 1))
    ThrowInputError(path, where, " is not a rigid transform");
  return Rigid3d(Eigen::Quaterniond(r).normalized(), m.topRightCorner<3, 1>());
}

PinholeCamera ReadCamera(const std::string& path,
                         const nlohmann::json& f,
                         const std::string& where) {
  PinholeCamera cam;
  cam.fx = JsonNumber(path, f.value("fx", nlohmann::json()), where + ".fx");
  cam.fy = JsonNumber(path, f.value("fy", nlohmann::json()), where + ".fy");
  cam.cx = JsonNumber(path, f.value("cx", nlohmann::json()), where + ".cx");
  cam.cy = JsonNumber(path, f.value("cy", nlohmann::json()), where + ".cy");
  const double w =
      JsonNumber(path, f.value("width", nlohmann::json()), where + ".width");
  const double h =
      JsonNumber(path, f.value("height", nlohmann::json()), where + ".height");
  if (w < 1 || h < 1 || w > 16384 || h > 16384 || w != std::floor(w) ||
      h != std::floor(h) || cam.fx <= 0 || cam.fy <= 0)
    ThrowInputError(path, where,
                    ": needs fx, fy > 0 and integer width, height in 1..16384");
  cam.width = static_cast<int>(w);
  cam.height = static_cast<int>(h);
  return cam;
}

class DepthFolderSceneSource : public SceneSource {
 public:
  SceneSourceTraits Traits() const override {
    return {true, false,
            "a folder with depth/000000.npy and cameras.json (per-frame K, "
            "world_from_cam)",
            "cameras.json"};
  }
  ConditionScene Build(const SceneInputs& in,
                       const SceneSourceOptions& options) const override {
    const std::string json_path = in.path + "/cameras.json";
    const nlohmann::json root = internal::ReadJsonObjectFile(json_path);
    const nlohmann::json& frames = root.value("frames", nlohmann::json());
    if (!frames.is_array() || frames.empty())
      ThrowInputError(json_path, "\"frames\" must be a non-empty array");
    if (in.clip && static_cast<int>(frames.size()) != in.clip->num_frames())
      ThrowInputError(json_path, "has ", frames.size(),
                      " frames but the clip has ", in.clip->num_frames());
    ConditionScene scene;
    scene.units = internal::JsonString(json_path, root, "units", "unknown");
    std::vector<Rigid3d> world_from_cam;
    for (size_t i = 0; i < frames.size(); ++i) {
      const std::string where = "frames[" + std::to_string(i) + "]";
      if (i == 0) scene.camera = ReadCamera(json_path, frames[i], where);
      world_from_cam.push_back(ReadPose(
          json_path, frames[i].value("world_from_cam", nlohmann::json()),
          where + ".world_from_cam"));
    }
    const std::string depth_path = in.path + "/depth/000000.npy";
    cv::Mat depth = ReadDepthNpy(depth_path);
    GEODRIVE_CHECK_INPUT(
        depth.cols == scene.camera.width && depth.rows == scene.camera.height,
        depth_path, ": depth is ", depth.cols, "x", depth.rows, " but ",
        json_path, " frames[0] is ", scene.camera.width, "x",
        scene.camera.height);
    if (options.filter == PointmapFilter::kPaper && scene.metric()) {
      depth.forEach<float>([&](float& d, const int*) {
        if (d < options.min_depth_m || d > options.max_depth_m)
          d = std::numeric_limits<float>::quiet_NaN();
      });
    }
    cv::Mat image = in.image;
    if (image.empty() && !in.image_path.empty())
      image = ReadImageRgb(in.image_path);
    if (image.empty() && in.clip)
      image = ReadImageRgb(in.clip->frames.front().image_path);
    GEODRIVE_CHECK_INPUT(!image.empty(), in.path,
                         ": no image for the colours (give --image or a clip)");
    scene.frame0_rgb = image.size() == depth.size()
                           ? image
                           : ResizeBilinear(image, depth.cols, depth.rows);
    scene.cloud =
        CloudFromDepth(depth, scene.frame0_rgb, scene.camera, Rigid3d());
    GEODRIVE_CHECK_INPUT(!scene.cloud.empty(), depth_path,
                         ": no pixel with valid depth");
    const Rigid3d cam0_from_world = world_from_cam.front().Inverse();
    for (size_t i = 0; i < world_from_cam.size(); ++i)
      scene.trajectory.Add(static_cast<double>(i),
                           cam0_from_world * world_from_cam[i]);
    scene.has_camera = true;
    scene.scale.source = scene.metric() ? "given" : "none";
    scene.scale.report = "units stated by " + json_path;
    scene.description = "depth folder " + in.path + " frame 0";
    return scene;
  }
};

}  // namespace
}  // namespace geodrive

GEODRIVE_DEFINE_SCENE_SOURCE(depth_folder, geodrive::DepthFolderSceneSource)
