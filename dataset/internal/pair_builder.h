#pragma once
// One clip -> one pair folder, the steps of `build-dataset` (internal to
// geodrive_dataset): load the clip, read its frames, build its scene, collect
// its boxes, render the condition, write the folder. Each step is a function
// so that BuildPair reads as the recipe.

#include <time.h>

#include <chrono>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "dataset/build_dataset.h"
#include "dataset/drive_dataset.h"
#include "dataset/exporter.h"
#include "dataset/pairs.h"
#include "dataset/scene_folders.h"
#include "dataset/scene_source.h"
#include "render/boxes.h"

namespace geodrive {
namespace internal {

// A failure inside one clip, tagged with the stage it happened in.
struct StageError : std::runtime_error {
  StageError(std::string s, const std::string& what)
      : std::runtime_error(what), stage(std::move(s)) {}
  std::string stage;
};

// Novel-view pairs share their source clip's scene: built once by the first
// pair that asks (the others of the clip wait for it), then copied by each,
// and released after the clip's last pair (a pair that fails before asking
// leaves it held until the run ends). The same scene as a build per pair.
class NovelViewScenes {
 public:
  // How many pairs of this run ask for each clip's scene.
  explicit NovelViewScenes(std::map<std::string, int> pairs_per_clip);
  // The scene of `clip_id`: `build()` run by the first caller; its
  // exception is every caller's.
  ConditionScene Get(const std::string& clip_id,
                     const std::function<ConditionScene()>& build);

 private:
  using Shared = std::shared_future<std::shared_ptr<const ConditionScene>>;
  std::mutex mutex_;
  std::map<std::string, int> remaining_;
  std::map<std::string, Shared> scenes_;
};

// What every clip of a run shares.
struct ClipContext {
  const DriveDataset* dataset = nullptr;
  // Index of each clip id in the dataset's clip list (upstream scene_idx).
  const std::map<std::string, int>* clip_index = nullptr;
  const BuildDatasetOptions* options = nullptr;
  // Per-clip input folders of path-based scene sources; null otherwise.
  const SceneFolders* folders = nullptr;
  // The run's exporters (BuildDatasetOptions::exports); null = none.
  const std::vector<std::unique_ptr<Exporter>>* exporters = nullptr;
  // Novel-view pairs (BuildDatasetOptions::lateral_offsets_m): pair id ->
  // source clip and offset; null or without the id = the pair of that clip.
  const std::map<std::string, PairNovelView>* novel_views = nullptr;
  // Their scenes, shared by the pairs of a clip; null = one per pair.
  NovelViewScenes* novel_scenes = nullptr;
};

// The dataset's options for a build: its clips and, with --cameras, its rig
// (the first camera listed is the reference; "all": CAM_FRONT).
DriveDatasetOptions DatasetOptionsOf(const BuildDatasetOptions& options);

// The clip's images: at source size (only for sources that colour from them;
// empty otherwise) and at the output size (the ground truth).
struct ClipFrames {
  // The first Traits().full_size_images frames at full size (colours).
  std::vector<cv::Mat> full;
  std::vector<cv::Mat> gt;
  // Frame 0's file (the upstream export reads it at full size).
  std::string first_frame_path;
};

// Stage-time keys with this prefix hold the worker thread's CPU seconds of
// the stage (the others wall seconds).
inline constexpr char kCpuStagePrefix[] = "cpu:";

// This thread's CPU seconds.
inline double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

// Times each stage into a map: wall time under the stage's name and this
// thread's CPU time under kCpuStagePrefix + name (the figure that holds on a
// shared machine; helper threads of a stage are not counted); tags exceptions
// with the stage.
class StageTimer {
 public:
  explicit StageTimer(std::map<std::string, double>* sink) : sink_(sink) {}
  template <typename F>
  auto Run(const std::string& stage, F&& f) -> decltype(f()) {
    const auto t0 = std::chrono::steady_clock::now();
    const double cpu0 = ThreadCpuSeconds();
    try {
      if constexpr (std::is_void_v<decltype(f())>) {
        f();
        Add(stage, t0, cpu0);
      } else {
        auto result = f();
        Add(stage, t0, cpu0);
        return result;
      }
    } catch (const StageError&) {
      Add(stage, t0, cpu0);
      throw;
    } catch (const std::exception& e) {
      Add(stage, t0, cpu0);
      throw StageError(stage, e.what());
    }
  }

 private:
  void Add(const std::string& stage,
           std::chrono::steady_clock::time_point t0,
           double cpu0) {
    (*sink_)[stage] +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
            .count();
    (*sink_)[kCpuStagePrefix + stage] += ThreadCpuSeconds() - cpu0;
  }
  std::map<std::string, double>* sink_;
};

// The condition frames at the output size, with their per-frame quality.
struct ConditionRender {
  std::vector<cv::Mat> frames;
  // The frames as the renderer made them, before the resize to the output
  // size (the released preset: 576x1024), for exports.
  std::vector<cv::Mat> native_frames;
  // Per frame at the output size, for exports: z-depth (CV_32F, the scene's
  // units, 0 = no point) and drawn mask (CV_8U, 255 = a point was drawn).
  std::vector<cv::Mat> depth, drawn;
  std::vector<double> coverage;
  std::vector<std::optional<double>> psnr_static;
  // Frame 0's depth as the renderer made it (CV_32F, camera z in the scene's
  // units, 0 = no point), at the render size (the output size for the
  // z-buffer presets): the surround-view seam check reads it.
  cv::Mat depth0;
  // lidar-dense: frame 0 before and after the depth completion (image |
  // projected returns | completed depth, CompletionPreview); empty otherwise.
  cv::Mat completion_preview;
};

// The before/after picture of a frame-0 depth completion: the frame-0 image,
// the projected LiDAR returns and the completed depth (colour = inverse depth,
// turbo, 2 m .. 80 m; black = none), each 400 px wide, labelled. Empty when
// the scene has no completion.
cv::Mat CompletionPreview(const ConditionScene& scene);

// PSNR (dB, data range 255) of RGB `a` against `b` over the pixels where
// `mask` (CV_8UC1, same size) != 0; nullopt if none. Integer sums, exact (the
// value summing in double gives). Frames at most 16384 wide.
std::optional<double> MaskedPsnr(const cv::Mat& a,
                                 const cv::Mat& b,
                                 const cv::Mat& mask);

// Reads the clip's images at the output size (dataset/frame_decode.h: a
// DCT-scaled decode, then a resize), and the first `full_size_images` (-1 =
// all) at full size too (ClipFrames::full); each is checked against the
// camera.
ClipFrames ReadClipFrames(const DriveClip& clip,
                          const BuildDatasetOptions& options,
                          int full_size_images);
// The clip's scene from the run's scene source; `path` is the clip's input
// folder for sources that read one (SceneFolders), empty otherwise.
ConditionScene BuildClipScene(const DriveClip& clip,
                              const std::vector<cv::Mat>& images,
                              const std::string& path,
                              const BuildDatasetOptions& options);
// Vehicle boxes of the clip: 3D in camera 0's frame (metric scenes only), 2D at
// the output size from the dataset's own camera poses.
BoxSequences ClipVehicleBoxes(const DriveClip& clip,
                              bool metric,
                              const BuildDatasetOptions& options);
// Same, the 3D boxes in the frame `scene_from_world` says (a rig's scene).
BoxSequences ClipVehicleBoxes(const DriveClip& clip,
                              bool metric,
                              const BuildDatasetOptions& options,
                              const Rigid3d& scene_from_world);
// What a render keeps beside the condition frames, for exports.
struct RenderKeep {
  // ConditionRender::native_frames.
  bool native_frames = false;
  // ConditionRender::depth and ::drawn.
  bool depth = false;
};
// Renders the scene along its trajectory with dynamic edits from `boxes`.
ConditionRender RenderCondition(const ConditionScene& scene,
                                const BoxSequences& boxes,
                                const std::vector<cv::Mat>& gt,
                                const BuildDatasetOptions& options,
                                const RenderKeep& keep = {});
// One camera's view of a scene: the cloud, the frame-0 camera on the source's
// grid (resized to the output as options say), the poses scene_from_cam per
// frame, units, the frame-0 dynamic mask.
struct ViewToRender {
  const PointCloud* cloud = nullptr;
  PinholeCamera camera;
  std::vector<Rigid3d> scene_from_cam;
  bool metric = true;
  cv::Mat dynamic_mask;
};
// RenderCondition for one view (a surround-view camera of a shared scene).
ConditionRender RenderConditionView(const ViewToRender& view,
                                    const BoxSequences& boxes,
                                    const std::vector<cv::Mat>& gt,
                                    const BuildDatasetOptions& options,
                                    const RenderKeep& keep = {});
// The pair's metadata (files and quality are filled by the writer).
PairMeta MakePairMeta(const DriveClip& clip,
                      const ConditionScene& scene,
                      const BuildDatasetOptions& options);
// The clip's LiDAR sweeps at frames 0, step, 2 step, ... (ExportSweep: the
// keyframe's own sweep, else the one nearest the frame's time), posed in the
// frame `scene_from_world` says. Throws InputError naming `format` when the
// clip has no LiDAR.
std::vector<ExportSweep> ClipSweeps(const DriveClip& clip,
                                    int step,
                                    const Rigid3d& scene_from_world,
                                    const std::string& format);
// Every annotated object of every frame (all categories, ExportObject), in
// the frame `scene_from_world` says, with its centre's speed.
std::vector<std::vector<ExportObject>> ClipObjects(
    const DriveClip& clip, const Rigid3d& scene_from_world);
// One exporter's view of a clip (ExportClip) with the frames and renders it
// points into: the pair's own, or a second render at the exporter's size.
struct ClipExport {
  const Exporter* exporter = nullptr;
  ClipFrames frames;
  ConditionRender cond;
  BoxSequences boxes;
  // LiDAR sweeps and objects, shared by the exporters that asked for them.
  std::shared_ptr<const std::vector<ExportSweep>> lidar;
  std::shared_ptr<const std::vector<std::vector<ExportObject>>> objects;
  // Points into the members above or into the pair's frames and render: not
  // copyable or movable once made.
  ExportClip clip;
  ClipExport() = default;
  ClipExport(const ClipExport&) = delete;
  ClipExport& operator=(const ClipExport&) = delete;
};
// Checks the clip against every exporter's requirements (the error names the
// first unmet one).
void CheckClipForExports(const ClipContext& ctx, const DriveClip& clip);
// An exporter's view's fields that come from the clip and the run: its id,
// scene and index in the clip list, each frame's source image and time (from
// `frames`, the camera's clip), the pair videos' x264 settings.
void SetExportClipSource(const ClipContext& ctx,
                         const std::string& clip_id,
                         const std::string& scene_name,
                         const DriveClip& frames,
                         ExportClip* ec);
// The clip's frames at an exporter's size (`eopt`'s), resized from full-size
// decodes: the pair's own (ClipFrames::full: every frame for the LiDAR scene
// sources) where it holds them, else each read here. Always the full decode
// (FullFrameToOutput), never the pair's DCT-scaled one, so an export's
// pixels do not depend on the scene source.
ClipFrames ExportFrames(const DriveClip& clip,
                        const ClipFrames& pair,
                        const BuildDatasetOptions& eopt);
// What the pair's render must keep for the exporters served at its size.
RenderKeep ExportRenderKeep(const ClipContext& ctx,
                            const BuildDatasetOptions& options);
// Every exporter's view of the clip: the pair's frames and render when the
// exporter takes the pair's size, a second read and render at its own size
// otherwise.
std::vector<std::unique_ptr<ClipExport>> PrepareClipExports(
    const ClipContext& ctx,
    const DriveClip& clip,
    const ConditionScene& scene,
    const ClipFrames& frames,
    const ConditionRender& cond,
    const BoxSequences& boxes);
// Encodes the videos and writes the pair folder into `dir`, with each
// export's files; fills meta.files.
void WritePairFolder(
    const std::string& dir,
    const ClipFrames& frames,
    const ConditionRender& cond,
    const BoxSequences& boxes,
    const BuildDatasetOptions& options,
    PairMeta* meta,
    const std::vector<std::unique_ptr<ClipExport>>& exports = {});

// Novel-view pairs (BuildDatasetOptions::lateral_offsets_m; build_dataset.cc).
// The source clip and offset of pair `pair_id`; null for a clip's own pair.
const PairNovelView* NovelViewOf(const ClipContext& ctx,
                                 const std::string& pair_id);
// Moves the scene's trajectory sideways by the view's offset
// (ShiftTrajectoryLaterally through frame 0's camera mounting). Throws
// InputError naming the clip when the scene is not metric.
void ShiftScene(const DriveClip& clip,
                const PairNovelView& view,
                ConditionScene* scene);
// The pair's id and novel_view in `meta`; the static-region PSNRs dropped
// from `cond` (the condition shows another view than the ground truth).
void MarkNovelView(const std::string& pair_id,
                   const PairNovelView& view,
                   ConditionRender* cond,
                   PairMeta* meta);

// Builds one surround-view pair (options.cameras; dataset/rig.h) into
// `tmp_dir`; returns its meta. Throws StageError.
PairMeta BuildRigPair(const ClipContext& ctx,
                      const std::string& clip_id,
                      const std::string& tmp_dir,
                      std::map<std::string, double>* stage_seconds);
// Builds one pair into `tmp_dir`; returns its meta. Throws StageError.
PairMeta BuildPair(const ClipContext& ctx,
                   const std::string& clip_id,
                   const std::string& tmp_dir,
                   std::map<std::string, double>* stage_seconds);

}  // namespace internal
}  // namespace geodrive
