// Scene source "cloud": a point cloud file (.ply, .pcd, nuScenes .pcd.bin,
// KITTI .bin; geometry/point_cloud_io.h) in its own world frame. A user
// trajectory must be in the same world (absolute poses). The camera comes from
// a K file for the render size (intrinsics_path) or from the caller (e.g. the
// trajectory JSON's "camera").

#include "dataset/scene/define.h"
#include "geometry/point_cloud_io.h"
#include "geometry/pointmap.h"

namespace geodrive {
namespace {

class CloudFileSceneSource : public SceneSource {
 public:
  SceneSourceTraits Traits() const override {
    return {true, false,
            "a point cloud file (.ply/.pcd/.pcd.bin/.bin) in the trajectory's "
            "world frame",
            /*folder_marker=*/""};
  }
  ConditionScene Build(const SceneInputs& in,
                       const SceneSourceOptions&) const override {
    ConditionScene scene;
    scene.cloud = ReadPointCloud(in.path);
    scene.anchor = TrajectoryAnchor::kAbsolute;
    if (!in.intrinsics_path.empty()) {
      scene.camera = ReadIntrinsicsFile(in.intrinsics_path, in.intrinsics_width,
                                        in.intrinsics_height);
      scene.has_camera = true;
    }
    scene.description = "cloud " + in.path;
    scene.scale.report = "units of the cloud file";
    return scene;
  }
};

}  // namespace
}  // namespace geodrive

GEODRIVE_DEFINE_SCENE_SOURCE(cloud_file, geodrive::CloudFileSceneSource)
