#pragma once
// The clip -> scene seam: a SceneSource turns a DriveClip (dataset/
// drive_clip.h) or the CLI's inputs (a cloud file, an image + depth, a
// MonST3R folder, ...) into a ConditionScene: the cloud to render, the poses
// of the frames, the camera, the frame-0 dynamic mask, units and a scale
// report. `geodrive render`, `geodrive build-dataset` and `geodrive-diffusion
// generate` all build their geometry here.
//
// Sources are plug-ins: one file each in dataset/scene/, registered by one
// line in dataset/scene/registry.inc, created by name (CreateSceneSource).
// docs/ARCHITECTURE.md walks through adding one.

#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "dataset/drive_clip.h"
#include "geometry/camera.h"
#include "geometry/depth_completion.h"
#include "geometry/point_cloud.h"
#include "geometry/trajectory.h"

namespace geodrive {

// Which pixels of a depth map or pointmap become points.
enum class PointmapFilter {
  // The paper's data engine: confidence >= tau, depth within [min, max]
  // (metric sources only), invalid depth dropped.
  kPaper,
  // The released inference scripts: every pixel with finite positive depth.
  kReleased,
};

// The sweeps the lidar-dense source projects into frame 0.
enum class LidarWindow {
  // Sweeps in [t0 - lidar_window_before_s, t0 + 50 ms] (the sweep in
  // progress at frame 0 included): what a car has at frame 0 (inference
  // time). The default.
  kCausal,
  // Sweeps over the whole clip, [t0 - lidar_window_before_s, last frame]:
  // denser, uses the future (StreetCrafter-style).
  kClip,
  // Sweeps in [t0 - lidar_window_before_s, t0 + lidar_window_after_s].
  kExplicit,
};
// "causal", "clip", "explicit"; Parse throws InputError for other text.
std::string ToString(LidarWindow window);
LidarWindow ParseLidarWindow(const std::string& text);

// What lidar-dense does with the returns inside annotated boxes (vehicles,
// pedestrians, ...).
enum class LidarObjects {
  // Dropped from every sweep: the static scene only (the objects' pixels
  // stay empty).
  kRemove,
  // Kept from the frame-0 sweep only (aggregating a moving object over
  // several sweeps would smear it): the objects are part of frame 0's
  // pointmap, as in a reconstruction's, and the dynamic editor moves them
  // along their boxes.
  kFrame0,
};
// "remove", "frame0"; Parse throws InputError for other text.
std::string ToString(LidarObjects objects);
LidarObjects ParseLidarObjects(const std::string& text);

// How a trajectory given by the user is placed in the scene frame.
enum class TrajectoryAnchor {
  // Its poses are in the scene frame as given (a cloud file and a trajectory
  // in the same world).
  kAbsolute,
  // Taken relative to its first pose, starting at the scene's frame-0 camera
  // (an image + depth, a reconstruction).
  kFirstFrame,
};

// How the geometry became metric (or why it is not).
struct SceneScale {
  // Metres per source unit applied to the geometry (1 when already metric).
  double scale = 1.0;
  // "lidar" (robust fit on LiDAR depth), "ego" (metric by construction:
  // LiDAR and ego poses), "given" (the source states its units) or "none".
  std::string source = "none";
  // One line on the fit, or why there is none.
  std::string report;
  // Inlier fraction of the LiDAR fit, when there was one.
  std::optional<double> inlier_fraction;
};

struct ConditionScene {
  // Points to render, in the scene frame: camera 0 for every source built
  // from a clip; the source's own world for sources with a world of their own
  // (a cloud file, a MonST3R folder rendered as released).
  PointCloud cloud;
  // The frames' poses scene_from_cam (camera axes OpenCV) with timestamps in
  // seconds; empty when the source has no trajectory (then the caller's
  // trajectory is placed by `anchor`).
  Trajectory trajectory;
  // How a user trajectory is placed in the scene frame.
  TrajectoryAnchor anchor = TrajectoryAnchor::kFirstFrame;
  // Pose of the frame-0 camera in the scene frame (identity for sources built
  // in camera 0's frame).
  Rigid3d scene_from_cam0;
  // Frame-0 camera on the source's own pixel grid (MonST3R's processed image,
  // the source image, ...). CameraAt() maps it to a render size.
  PinholeCamera camera;
  // True when `camera` is known (a cloud file may come without one).
  bool has_camera = false;
  // Frame-0 dynamic mask on `camera`'s grid (CV_8U, nonzero = dynamic);
  // empty when the source has none.
  cv::Mat dynamic_mask;
  // Frame-0 colour image (RGB) on `camera`'s grid; empty when unknown.
  cv::Mat frame0_rgb;
  // Images of the source's own frames (for contact sheets), when it has them.
  std::vector<std::string> frame_image_paths;
  // "metres", "monst3r" (MonST3R units) or "unknown".
  std::string units = "unknown";
  SceneScale scale;
  // One line: what was read ("MonST3R DIR frame 0", "cloud FILE", ...).
  std::string description;
  // Seconds spent per step inside the source (e.g. "scale" for a LiDAR fit).
  std::map<std::string, double> seconds;
  // Reprojection RMS (px) over static pixels before and after the pose
  // refinement (paper eq. 3), when the source ran it.
  std::optional<double> reprojection_rms_px_before;
  std::optional<double> reprojection_rms_px_after;
  // Frame-0 depth completion (lidar-dense): support and coverage, the
  // accuracy on held-out returns of the frame-0 sweep, and the depth before
  // (the projected returns) and after completion on `camera`'s grid (CV_32F,
  // metres, 0 = none) for previews.
  std::optional<DepthCompletionReport> completion;
  std::optional<DepthCompletionAccuracy> completion_accuracy;
  cv::Mat completion_sparse, completion_dense;

  bool metric() const { return units == "metres"; }
  // The frame-0 camera for an output of width x height, resized (and
  // cropped) as `mode` says.
  PinholeCamera CameraAt(int width, int height, ResizeMode mode) const;
  // A user trajectory in the scene frame, placed as `anchor` says.
  Trajectory PlaceTrajectory(const Trajectory& user) const;
};

struct SceneSourceOptions {
  // Pixel filter for depth-based sources.
  PointmapFilter filter = PointmapFilter::kPaper;
  // Confidence threshold tau in [0, 1] (paper 0.65; kPaper only).
  double min_confidence = 0.65;
  // Depth range in metres kept by kPaper when the scene is metric.
  double min_depth_m = 0.1;
  double max_depth_m = 100.0;
  // Fit a metric scale against the clip's LiDAR (relative-depth sources with
  // a clip that has LiDAR).
  bool lidar_scale = true;
  // Refine the reconstruction's poses by reprojection least squares over
  // static confident pixels (paper eq. 3; MonST3R source, kPaper).
  bool refine_poses = false;
  // LiDAR aggregation: sweeps within [t0 - before, t0 + after] seconds.
  double lidar_window_before_s = 0.5;
  double lidar_window_after_s = 1.5;
  // lidar-dense: the window policy (the "lidar" source always uses
  // [t0 - before, t0 + after]).
  LidarWindow dense_window = LidarWindow::kCausal;
  // lidar-dense: the returns inside annotated boxes.
  LidarObjects dense_objects = LidarObjects::kRemove;
  // lidar-dense: width (pixels) of the frame-0 depth image that is completed
  // and unprojected (the frame-0 camera scaled to it; 0 = the camera's own).
  int dense_width = 800;
  // lidar-dense: the completion (geometry/depth_completion.h).
  DepthCompletionOptions completion;
  // True if every field is in range.
  bool Check() const;
};

// Bytes the lidar-dense source holds for a frame-0 depth of `width` x
// `height`: per pixel the resized image, the sparse and completed depths (and
// the held-out run's), the completion's scratch images and the unprojected
// cloud (positions and colours, with a vector's growth), about
// kLidarDenseBytesPerPixel.
constexpr uint64_t kLidarDenseBytesPerPixel = 80;
uint64_t EstimateLidarDenseBytes(int64_t width, int64_t height);
// Throws InputError naming `what` (e.g. "--lidar-dense-width 16384") with the
// estimate when a `width` x `height` lidar-dense depth does not fit in the
// memory available (AvailableMemoryBytes, geometry/util/memory.h).
void CheckLidarDenseMemory(const std::string& what,
                           int64_t width,
                           int64_t height);

struct SceneInputs {
  // The clip the scene is built for; null for CLI inputs without a clip.
  const DriveClip* clip = nullptr;
  // The clip's decoded images at source size, when the caller has them
  // (colours for the LiDAR sources: the first Traits().full_size_images of
  // them); read from disk otherwise.
  const std::vector<cv::Mat>* clip_images = nullptr;
  // The source's own input: a MonST3R folder, a cloud file, a depth .npy, a
  // depth folder.
  std::string path;
  // Frame-0 image (RGB) for sources without colours of their own: decoded
  // (`image`) or a file to read (`image_path`, also named in errors).
  cv::Mat image;
  std::string image_path;
  // K file (9 numbers) for depth and cloud sources; empty for none.
  std::string intrinsics_path;
  // Size of the image `intrinsics_path` is for (cloud sources: the render
  // size); 0 = the depth map's size.
  int intrinsics_width = 0, intrinsics_height = 0;
};

// What a source needs.
struct SceneSourceTraits {
  // SceneInputs::path is required (and per clip it is ROOT/<clip id>).
  bool needs_path = true;
  // SceneInputs::clip is required.
  bool needs_clip = false;
  // One line for --help: what the source reads.
  std::string help;
  // A file that marks the source's folder (per-clip folder layouts,
  // dataset/scene_folders.h); empty = none.
  std::string folder_marker;
  // How many of the clip's images the source colours from at full size
  // (SceneInputs::clip_images; the builder decodes only these at full size):
  // 0, 1 (frame 0) or -1 (all).
  int full_size_images = 0;
};

class SceneSource {
 public:
  virtual ~SceneSource() = default;
  virtual SceneSourceTraits Traits() const = 0;
  // Builds the scene. Throws InputError naming the file and what is wrong.
  virtual ConditionScene Build(const SceneInputs& inputs,
                               const SceneSourceOptions& options) const = 0;
};

// The registered source names, in registry order ("monst3r", "lidar", ...).
std::vector<std::string> SceneSourceNames();
// The source called `name`; throws InputError listing the names otherwise.
std::unique_ptr<SceneSource> CreateSceneSource(const std::string& name);
// CreateSceneSource(name)->Build(inputs, options), after checking the inputs
// against the source's traits.
ConditionScene BuildConditionScene(const std::string& name,
                                   const SceneInputs& inputs,
                                   const SceneSourceOptions& options);

// A `--scene` argument: "TOOL:PATH" (TOOL a reconstruction format of
// geometry/reconstruction.h: monst3r, vggt, da3, cut3r, megasam, moge, npz)
// or a PATH whose format is detected. Returns {scene source name, path};
// throws InputError naming the argument otherwise.
std::pair<std::string, std::string> ParseSceneArgument(const std::string& text);

}  // namespace geodrive
