// Scene source "image-depth": one RGB image with its z-depth map (.npy, same
// size) and K: every pixel with finite positive depth, unprojected at its
// integer index, in the image's camera frame (= camera 0). A user trajectory
// is taken relative to its first pose.

#include "dataset/scene/define.h"
#include "geometry/image_io.h"
#include "geometry/pointmap.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

class ImageDepthSceneSource : public SceneSource {
 public:
  SceneSourceTraits Traits() const override {
    return {true, false,
            "an image (SceneInputs::image or image_path), its z-depth .npy "
            "(path) and a K file (intrinsics_path)",
            /*folder_marker=*/""};
  }
  ConditionScene Build(const SceneInputs& in,
                       const SceneSourceOptions&) const override {
    const std::string image_name =
        in.image_path.empty() ? std::string("the image") : in.image_path;
    const cv::Mat image = in.image.empty() && !in.image_path.empty()
                              ? ReadImageRgb(in.image_path)
                              : in.image;
    GEODRIVE_CHECK_INPUT(!image.empty(), in.path,
                         ": a depth map needs its image (--image)");
    GEODRIVE_CHECK_INPUT(!in.intrinsics_path.empty(), in.path,
                         ": a depth map needs its K (--intrinsics K.txt)");
    const cv::Mat depth = ReadDepthNpy(in.path);
    GEODRIVE_CHECK_INPUT(depth.size() == image.size(), in.path, ": depth is ",
                         depth.cols, "x", depth.rows, " but ", image_name,
                         " is ", image.cols, "x", image.rows);
    ConditionScene scene;
    scene.camera =
        ReadIntrinsicsFile(in.intrinsics_path, depth.cols, depth.rows);
    scene.has_camera = true;
    scene.cloud = CloudFromDepth(depth, image, scene.camera, Rigid3d());
    scene.anchor = TrajectoryAnchor::kFirstFrame;
    scene.frame0_rgb = image;
    scene.description = "image " + in.image_path + " + depth " + in.path;
    scene.scale.report = "units of the depth map";
    return scene;
  }
};

}  // namespace
}  // namespace geodrive

GEODRIVE_DEFINE_SCENE_SOURCE(image_depth, geodrive::ImageDepthSceneSource)
