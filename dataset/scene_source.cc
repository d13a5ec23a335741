#include "dataset/scene_source.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "geometry/reconstruction.h"
#include "geometry/util/memory.h"
#include "geometry/util/status.h"
#include "render/footprint.h"
#include "render/video/video_io.h"

// Every source's factory, declared from the registry list.
#define GEODRIVE_SCENE_SOURCE(identifier, name) \
  std::unique_ptr<::geodrive::SceneSource> CreateSceneSource_##identifier();
#include "dataset/scene/registry.inc"
#undef GEODRIVE_SCENE_SOURCE

namespace geodrive {
namespace {

struct Entry {
  const char* name;
  std::unique_ptr<SceneSource> (*create)();
};

const std::vector<Entry>& Registry() {
#define GEODRIVE_SCENE_SOURCE(identifier, name) \
  Entry{name, &::CreateSceneSource_##identifier},
  static const std::vector<Entry> entries = {
#include "dataset/scene/registry.inc"
  };
#undef GEODRIVE_SCENE_SOURCE
  return entries;
}

}  // namespace

PinholeCamera ConditionScene::CameraAt(int width,
                                       int height,
                                       ResizeMode mode) const {
  return ApplyResizeSpec(camera, ComputeResizeSpec(camera.width, camera.height,
                                                   width, height, mode));
}

Trajectory ConditionScene::PlaceTrajectory(const Trajectory& user) const {
  if (anchor == TrajectoryAnchor::kAbsolute) return user;
  Trajectory placed = user.RelativeToFirst();
  const bool identity =
      scene_from_cam0.rotation.coeffs() == Eigen::Vector4d(0, 0, 0, 1) &&
      scene_from_cam0.translation == Eigen::Vector3d::Zero();
  if (identity) return placed;  // keeps the poses bit-exact
  for (auto& pose : placed.world_from_cam) pose = scene_from_cam0 * pose;
  return placed;
}

uint64_t EstimateLidarDenseBytes(int64_t width, int64_t height) {
  return static_cast<uint64_t>(std::max<int64_t>(width, 0)) *
         static_cast<uint64_t>(std::max<int64_t>(height, 0)) *
         kLidarDenseBytesPerPixel;
}

void CheckLidarDenseMemory(const std::string& what,
                           int64_t width,
                           int64_t height) {
  const uint64_t need = EstimateLidarDenseBytes(width, height);
  const uint64_t available = AvailableMemoryBytes();
  GEODRIVE_CHECK_INPUT(need <= available, what,
                       ": a lidar-dense frame-0 depth of ", width, "x", height,
                       " needs about ", (need + (1 << 20) - 1) >> 20,
                       " MiB, and ", available >> 20, " MiB are available");
}

bool SceneSourceOptions::Check() const {
  return min_confidence >= 0 && min_confidence <= 1 && min_depth_m >= 0 &&
         max_depth_m > min_depth_m && std::isfinite(lidar_window_before_s) &&
         std::isfinite(lidar_window_after_s) && lidar_window_before_s >= 0 &&
         lidar_window_after_s >= 0 && dense_width >= 0 &&
         dense_width <= 16384 && completion.Check();
}

std::string ToString(LidarWindow window) {
  switch (window) {
    case LidarWindow::kCausal:
      return "causal";
    case LidarWindow::kClip:
      return "clip";
    case LidarWindow::kExplicit:
      return "explicit";
  }
  return "causal";
}

LidarWindow ParseLidarWindow(const std::string& text) {
  for (LidarWindow w :
       {LidarWindow::kCausal, LidarWindow::kClip, LidarWindow::kExplicit}) {
    if (text == ToString(w)) return w;
  }
  throw InputError("LiDAR window '" + text +
                   "': expected causal, clip or explicit");
}

std::string ToString(LidarObjects objects) {
  return objects == LidarObjects::kRemove ? "remove" : "frame0";
}

LidarObjects ParseLidarObjects(const std::string& text) {
  if (text == "remove") return LidarObjects::kRemove;
  if (text == "frame0") return LidarObjects::kFrame0;
  throw InputError("LiDAR objects '" + text + "': expected remove or frame0");
}

std::vector<std::string> SceneSourceNames() {
  std::vector<std::string> names;
  for (const Entry& e : Registry()) names.push_back(e.name);
  return names;
}

std::unique_ptr<SceneSource> CreateSceneSource(const std::string& name) {
  // Reconstructions that keep their images in a video (the GEN3C export).
  RegisterVideoDecoderForReconstructions();
  for (const Entry& e : Registry()) {
    if (name == e.name) return e.create();
  }
  std::ostringstream os;
  for (const Entry& e : Registry())
    os << (os.tellp() > 0 ? ", " : "") << e.name;
  throw InputError("unknown scene source '" + name + "' (expected one of " +
                   os.str() + ")");
}

ConditionScene BuildConditionScene(const std::string& name,
                                   const SceneInputs& inputs,
                                   const SceneSourceOptions& options) {
  const std::unique_ptr<SceneSource> source = CreateSceneSource(name);
  const SceneSourceTraits traits = source->Traits();
  GEODRIVE_CHECK_INPUT(options.Check(), "scene source ", name,
                       ": options out of range (confidence in [0, 1], 0 <= "
                       "min depth < max depth, LiDAR window >= 0)");
  GEODRIVE_CHECK_INPUT(!traits.needs_path || !inputs.path.empty(),
                       "scene source ", name, " needs an input path (",
                       traits.help, ")");
  GEODRIVE_CHECK_INPUT(!traits.needs_clip || inputs.clip, "scene source ", name,
                       " needs a dataset clip (", traits.help, ")");
  ConditionScene scene = source->Build(inputs, options);
  // Capture footprints for footprint-aware splats (render/footprint.h): the
  // cloud as seen by the frame-0 camera on the source's own grid, unless the
  // source set its own.
  if (scene.has_camera && !scene.cloud.HasFootprints())
    SetCaptureFootprints(scene.camera, scene.scene_from_cam0.Inverse(),
                         &scene.cloud);
  return scene;
}

std::pair<std::string, std::string> ParseSceneArgument(
    const std::string& text) {
  GEODRIVE_CHECK_INPUT(!text.empty(), "--scene", ": empty argument");
  const size_t colon = text.find(':');
  // "vggt:out/predictions.npz"; a colon after the first '/' is part of a path.
  if (colon != std::string::npos && colon > 0 && text.find('/') > colon) {
    const ReconstructionFormat format =
        ParseReconstructionFormat(text.substr(0, colon));
    return {ToString(format), text.substr(colon + 1)};
  }
  const std::optional<ReconstructionFormat> format =
      DetectReconstructionFormat(text);
  GEODRIVE_CHECK_INPUT(format, text,
                       ": not a reconstruction this reader recognises; name "
                       "the tool as TOOL:PATH (monst3r, vggt, da3, cut3r, "
                       "megasam, moge, npz)");
  return {ToString(*format), text};
}

}  // namespace geodrive
