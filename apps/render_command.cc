// `geodrive render`: conditioning videos by point splatting along a trajectory.
//
//   geodrive render (--cloud FILE.ply | --image IMG --depth DEPTH.npy
//   --intrinsics K.txt |
//                    --monst3r DIR) --trajectory FILE [--shift-left 3]
//                    [--reverse]
//                   [--mode zbuffer|soft] [--preset
//                   paper|footprint|geodrive-compat]
//                   [--size 480x720]
//                   [--fps 10] [--frames] --out DIR
//
// Writes DIR/render.mp4 (H.264 via OpenCV/FFmpeg, mp4v fallback),
// DIR/contact_sheet.png, DIR/render.json (options, codec, per-frame coverage)
// and with --frames the lossless PNG sequence DIR/frames/render_NNNN.png.
// Dynamic editing: --boxes FILE [--edit-mode 3d|2d] [--remove ID]
// [--insert ID:FILE] [--move ID:FILE] (render/dynamic_edit.h); the applied
// edits and notes go to render.json "dynamic_edit".

#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>
#include <thread>
#include <tuple>

#include "apps/cli/cli.h"
#include "apps/cli/edit_args.h"
#include "dataset/scene_source.h"
#include "geometry/image_io.h"
#include "geometry/trajectory_edit.h"
#include "geometry/trajectory_json.h"
#include "geometry/util/files.h"
#include "geometry/util/memory.h"
#include "geometry/util/status.h"
#include "render/dynamic_edit.h"
#include "render/presets.h"
#include "render/renderer.h"
#include "render/video/video.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

struct RenderArgs {
  std::string cloud, image, depth, intrinsics, monst3r, scene, trajectory, out;
  std::string trajectory_format = "auto";
  std::string mode, preset = "paper", size;
  // Overrides of the preset's values (absent: the preset's).
  std::optional<double> radius;
  std::optional<int> points_per_pixel;
  std::optional<double> near, far;
  std::optional<double> max_magnification;
  bool hole_fill = false;
  TrajectoryEditOptions edits;
  bool reverse = false;
  double fps = 10;
  bool frames = false;
  bool no_video = false;
  std::string real_frame0;
  int threads = 0;
  EditCliArgs dynamic;  // --boxes, --edit-mode, --remove, --insert, --move
};

std::string Fixed(double v, int digits) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(digits) << v;
  return os.str();
}

// The renderer's options: the preset's, overridden by the flags given.
RenderOptions RenderOptionsFromArgs(const RenderArgs& a, RenderPreset preset) {
  RenderOptions options = PresetRenderOptions(preset);
  if (!a.mode.empty()) options.mode = ParseRenderMode(a.mode);
  if (!a.size.empty())
    ParseSizeHxW(a.size, "--size", &options.height, &options.width);
  if (a.radius) {
    if (options.mode == RenderMode::kSoft) {
      options.radius_ndc = *a.radius;
    } else {
      options.radius_px = *a.radius;
    }
  }
  if (a.points_per_pixel) options.points_per_pixel = *a.points_per_pixel;
  if (a.near) options.near = *a.near;
  if (a.far) options.far = *a.far;
  if (a.max_magnification)
    options.max_footprint_magnification = *a.max_magnification;
  options.hole_fill = a.hole_fill;
  options.num_threads = a.threads;
  if (options.mode == RenderMode::kSoft) options.output_float_rgb = true;
  options.Check();
  return options;
}

// The scene (dataset/scene_source.h) and the trajectory in its frame.
struct RenderInput {
  ConditionScene scene;
  Trajectory trajectory;
  PinholeCamera camera;
  std::string units = "unknown";
  cv::Mat real_frame0;
  // The scene's own frames (MonST3R's RGB), read one at a time when the
  // contact sheet is made.
  std::vector<std::string> ground_truth_paths;
};

RenderInput LoadRenderInput(const RenderArgs& a, const RenderOptions& options) {
  RenderInput r;
  bool have_camera = false;
  TrajectoryFileInfo traj_info;
  if (!a.trajectory.empty()) {
    r.trajectory = ReadTrajectoryAny(
        a.trajectory, ParseTrajectoryFormat(a.trajectory_format), &traj_info);
    r.trajectory.Check(a.trajectory);
    r.units = traj_info.units;
    if (traj_info.camera) {
      r.camera = *traj_info.camera;
      have_camera = true;
    }
  }
  SceneInputs in;
  std::string source;
  if (!a.cloud.empty()) {
    // The trajectory is in the cloud's world frame (absolute poses);
    // --intrinsics with --cloud: K for an image of the render size.
    source = "cloud";
    in.path = a.cloud;
    in.intrinsics_path = a.intrinsics;
    in.intrinsics_width = options.width;
    in.intrinsics_height = options.height;
  } else if (!a.image.empty()) {
    source = "image-depth";
    in.path = a.depth;
    in.image_path = a.image;
    in.intrinsics_path = a.intrinsics;
  } else if (!a.scene.empty()) {
    std::tie(source, in.path) = ParseSceneArgument(a.scene);
  } else {
    source = "monst3r";
    in.path = a.monst3r;
  }
  SceneSourceOptions scene_options;
  scene_options.filter = PointmapFilter::kReleased;  // as the released scripts
  r.scene = BuildConditionScene(source, in, scene_options);
  const ConditionScene& scene = r.scene;
  if (scene.has_camera) {
    r.camera = scene.camera;
    have_camera = true;
  }
  if (scene.units != "unknown") r.units = scene.units;
  r.real_frame0 = scene.frame0_rgb;
  if (a.trajectory.empty()) {
    r.trajectory = scene.trajectory;
    r.ground_truth_paths = scene.frame_image_paths;
  } else {
    r.trajectory = scene.PlaceTrajectory(r.trajectory);
  }
  GEODRIVE_CHECK_INPUT(!scene.cloud.empty(), scene.description,
                       ": no points (empty cloud or no valid depth)");
  GEODRIVE_CHECK_INPUT(
      have_camera, a.trajectory,
      ": no camera intrinsics: with --cloud the "
      "trajectory JSON must hold a \"camera\" (or use --image/--monst3r)");

  return r;
}

// What render.json keeps of one frame (the frames themselves are streamed to
// the outputs and dropped).
struct FrameStats {
  double coverage = 0;
  int64_t num_valid = 0, num_filled = 0, num_projected = 0;
};

// render.json: inputs, options, camera, per-frame coverage, summary.
json RenderReport(const RenderArgs& a,
                  const RenderInput& in,
                  const Trajectory& edited,
                  RenderPreset preset,
                  const RenderOptions& options,
                  bool frame0_replaced,
                  const std::vector<FrameStats>& stats,
                  const RenderSummary& summary,
                  cv::Size output_size,
                  const json& dynamic_edit,
                  json report) {
  const PinholeCamera& camera = in.camera;
  report["input"] = in.scene.description;
  report["trajectory"] = !a.trajectory.empty() ? a.trajectory
                         : !a.scene.empty()    ? a.scene + " (its camera poses)"
                                               : a.monst3r + "/pred_traj.txt";
  report["units"] = in.units;
  report["edits"] = a.edits.Describe();
  if (!dynamic_edit.is_null()) report["dynamic_edit"] = dynamic_edit;
  report["preset"] = ToString(preset);
  report["options"] = {
      {"mode", ToString(options.mode)},
      {"height", options.height},
      {"width", options.width},
      {"near", options.near},
      {"far", std::isfinite(options.far) ? json(options.far) : json("inf")},
      {"radius_px", options.radius_px},
      {"radius_ndc", options.radius_ndc},
      {"splat_size", ToString(options.splat_size)},
      {"max_footprint_magnification", options.max_footprint_magnification},
      {"points_per_pixel", options.points_per_pixel},
      {"pixel_convention",
       options.pixel_convention == PixelConvention::kPixelCenter
           ? "pixel-center"
           : "integer-index"},
      {"hole_fill", options.hole_fill},
      {"upsample", PresetUpsampleFactor(preset)},
      {"frame0_replaced", frame0_replaced}};
  report["camera"] = {{"fx", camera.fx},       {"fy", camera.fy},
                      {"cx", camera.cx},       {"cy", camera.cy},
                      {"width", camera.width}, {"height", camera.height}};
  report["num_points"] = in.scene.cloud.size();
  report["output_size"] = {{"width", output_size.width},
                           {"height", output_size.height}};
  json per_frame = json::array();
  for (size_t f = 0; f < stats.size(); ++f) {
    const FrameStats& fr = stats[f];
    per_frame.push_back({{"frame", f},
                         {"t", edited.timestamps[f]},
                         {"coverage", fr.coverage},
                         {"valid_pixels", fr.num_valid},
                         {"filled_pixels", fr.num_filled},
                         {"points_in_view", fr.num_projected}});
  }
  report["frames"] = per_frame;
  report["summary"] = {{"mean_coverage", summary.mean_coverage},
                       {"min_coverage", summary.min_coverage},
                       {"max_coverage", summary.max_coverage},
                       {"all_invalid_frames", summary.empty_frames},
                       {"seconds", summary.seconds}};
  return report;
}

// Frames drawn on contact_sheet.png: all of a clip up to this many, else this
// many evenly spaced (a 3000-frame sheet would be a 100-megapixel PNG).
constexpr int kMaxContactSheetFrames = 100;

// How many frames the render holds at once, and with how many threads, so
// that the job fits in the memory this process may use (AvailableMemoryBytes):
// throws InputError when not even one frame on one thread fits. Streaming
// renders hold a chunk of frames; dynamic editing holds the whole clip.
struct RenderMemoryPlan {
  int chunk = 1;
  int threads = 1;
};
RenderMemoryPlan PlanRenderMemory(const RenderOptions& options,
                                  RenderPreset preset,
                                  int64_t num_points,
                                  int num_frames,
                                  int requested_threads,
                                  bool whole_clip) {
  const int factor = PresetUpsampleFactor(preset);
  // A final (upsampled) RGB frame, and the encoder's padded copy and YUV.
  const uint64_t final_bytes =
      uint64_t{3} * options.width * factor * options.height * factor;
  auto need = [&](int chunk, int threads) {
    return EstimateRenderBytes(options, num_points, chunk, threads) +
           static_cast<uint64_t>(chunk) * final_bytes + 3 * final_bytes;
  };
  const uint64_t available = AvailableMemoryBytes();
  const uint64_t budget =
      available == UINT64_MAX ? available : available / 10 * 8;
  const int hw =
      static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  RenderMemoryPlan plan;
  plan.threads =
      std::min(requested_threads > 0 ? requested_threads : hw, num_frames);
  auto gib = [](uint64_t b) { return Fixed(b / double(1ull << 30), 2); };
  if (whole_clip) {
    plan.chunk = num_frames;
    while (plan.threads > 1 && need(plan.chunk, plan.threads) > budget)
      --plan.threads;
    GEODRIVE_CHECK_INPUT(
        need(plan.chunk, plan.threads) <= budget,
        "render: dynamic editing "
        "holds all ",
        num_frames, " frames of ", options.width, "x", options.height,
        ": about ", gib(need(plan.chunk, 1)), " GiB, more than the ",
        gib(budget),
        " GiB this process may use (fewer frames or a smaller --size)");
    return plan;
  }
  plan.chunk = std::min(num_frames, std::max(8, 2 * plan.threads));
  while (plan.chunk > 1 && need(plan.chunk, plan.threads) > budget) {
    plan.chunk = std::max(1, plan.chunk / 2);
    plan.threads = std::min(plan.threads, plan.chunk);
  }
  while (plan.threads > 1 && need(plan.chunk, plan.threads) > budget)
    --plan.threads;
  GEODRIVE_CHECK_INPUT(need(1, 1) <= budget, "render: one ", options.width, "x",
                       options.height, " ", ToString(options.mode),
                       " frame from ", num_points, " points needs about ",
                       gib(need(1, 1)), " GiB, more than the ", gib(budget),
                       " GiB this process may use (a smaller --size)");
  return plan;
}

// Accumulates per-frame statistics into the summary RenderFrames gives.
void AddToSummary(const RenderedFrame& frame,
                  int index,
                  RenderSummary* summary,
                  std::vector<FrameStats>* stats) {
  FrameStats s;
  s.coverage = frame.coverage();
  s.num_valid = frame.num_valid;
  s.num_filled = frame.num_filled;
  s.num_projected = frame.num_projected;
  stats->push_back(s);
  if (summary->num_frames == 0) {
    summary->min_coverage = 1.0;
    summary->max_coverage = 0.0;
  }
  ++summary->num_frames;
  summary->mean_coverage += s.coverage;  // a sum until the end
  summary->min_coverage = std::min(summary->min_coverage, s.coverage);
  summary->max_coverage = std::max(summary->max_coverage, s.coverage);
  if (frame.num_valid == 0) summary->empty_frames.push_back(index);
}

// Which frames the contact sheet draws: every frame, or
// kMaxContactSheetFrames evenly spaced.
std::vector<char> ContactSheetSelection(int num_frames) {
  std::vector<char> on_sheet(num_frames, num_frames <= kMaxContactSheetFrames);
  for (int k = 0;
       num_frames > kMaxContactSheetFrames && k < kMaxContactSheetFrames; ++k) {
    on_sheet[static_cast<int64_t>(k) * (num_frames - 1) /
             (kMaxContactSheetFrames - 1)] = 1;
  }
  return on_sheet;
}

// Checks the command line's combination of inputs (RunRender's first step).
void CheckRenderArgs(const RenderArgs& a) {
  const int sources = !a.cloud.empty() + !a.image.empty() + !a.monst3r.empty() +
                      !a.scene.empty();
  GEODRIVE_CHECK_INPUT(
      sources == 1,
      "give exactly one input: --cloud, --image (with --depth, --intrinsics), "
      "--monst3r or --scene");
  if (!a.image.empty()) {
    GEODRIVE_CHECK_INPUT(
        !a.depth.empty() && !a.intrinsics.empty(),
        "--image needs --depth DEPTH.npy and --intrinsics K.txt");
  }
  GEODRIVE_CHECK_INPUT(
      !a.trajectory.empty() || !a.monst3r.empty() || !a.scene.empty(),
      "--trajectory is required (except with --monst3r or --scene, which "
      "default to the reconstruction's own camera poses)");
  GEODRIVE_CHECK_INPUT(!a.dynamic.boxes_path.empty() ||
                           (a.dynamic.remove.empty() &&
                            a.dynamic.insert.empty() && a.dynamic.move.empty()),
                       "--remove/--insert/--move need --boxes FILE");
}

int RunRender(RenderArgs a) {
  CheckRenderArgs(a);
  const RenderPreset preset = ParseRenderPreset(a.preset);
  const RenderOptions base_options = RenderOptionsFromArgs(a, preset);
  a.edits.forward_then_back = a.reverse;
  a.edits.Check();
  // An unusable --out fails before anything is read or rendered.
  CreateOutputDirectory(a.out);

  const RenderInput in = LoadRenderInput(a, base_options);
  const PointCloud& cloud = in.scene.cloud;
  const PinholeCamera& camera = in.camera;
  cv::Mat real_frame0 = in.real_frame0;
  std::vector<std::string> ground_truth_paths = in.ground_truth_paths;

  const Trajectory edited = ApplyTrajectoryEdits(in.trajectory, a.edits);
  if (edited.size() != ground_truth_paths.size() ||
      a.edits.Describe() != "none")
    ground_truth_paths.clear();
  std::vector<Rigid3d> cam_from_world;
  for (const auto& pose : edited.world_from_cam)
    cam_from_world.push_back(pose.Inverse());
  const int num_frames = static_cast<int>(cam_from_world.size());
  if (!a.real_frame0.empty()) real_frame0 = ReadImageRgb(a.real_frame0);

  // ---- Render, streaming chunks of frames to the outputs ----
  const bool dynamic = !a.dynamic.boxes_path.empty();
  const RenderMemoryPlan plan =
      PlanRenderMemory(base_options, preset, cloud.size(), num_frames,
                       a.threads, /*whole_clip=*/dynamic);
  RenderOptions options = base_options;
  // Threads: as asked (0 = OpenMP's default), fewer only when memory says so.
  const int hw =
      static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (a.threads > 0 || plan.threads < std::min(hw, num_frames))
    options.num_threads = plan.threads;
  // Frame 0 is replaced by the real image only in the compat preset (the
  // released pipeline).
  const cv::Mat frame0_replacement =
      preset == RenderPreset::kGeodriveCompat ? real_frame0 : cv::Mat();
  const int factor = PresetUpsampleFactor(preset);
  const cv::Size output_size(options.width * factor, options.height * factor);
  const std::vector<char> on_sheet = ContactSheetSelection(num_frames);

  json report, dynamic_edit;
  std::unique_ptr<VideoStreamWriter> video;
  if (!a.no_video) {
    VideoWriteOptions vo;
    vo.fps = a.fps;
    video = std::make_unique<VideoStreamWriter>(
        (fs::path(a.out) / "render.mp4").string(), output_size.width,
        output_size.height, vo);
  }
  std::vector<cv::Mat> thumbs, gt_thumbs;
  std::vector<FrameStats> stats;
  RenderSummary summary;
  summary.num_points = static_cast<int64_t>(cloud.size());
  RenderResult chunk;
  for (int start = 0; start < num_frames; start += plan.chunk) {
    const int end = std::min(num_frames, start + plan.chunk);
    const std::vector<Rigid3d> poses(cam_from_world.begin() + start,
                                     cam_from_world.begin() + end);
    if (dynamic) {  // the whole clip at once (plan.chunk == num_frames)
      DynamicEditResult result = ApplyEditsAndRender(
          a.dynamic, cloud, {camera}, poses, options, real_frame0);
      dynamic_edit = json::parse(result.summary.ToJson());
      std::cout << result.summary.BriefReport() << "\n";
      chunk = std::move(result).ToRenderResult();
    } else {
      RenderFramesInto(cloud, {camera}, poses, options, &chunk);
    }
    summary.seconds += chunk.summary.seconds;
    const std::vector<cv::Mat> frames =
        FinalFrames(chunk, preset, start == 0 ? frame0_replacement : cv::Mat());
    for (int i = 0; i < end - start; ++i) {
      AddToSummary(chunk.frames[i], start + i, &summary, &stats);
      if (video) video->Write(frames[i]);
      if (!on_sheet[start + i]) continue;
      thumbs.push_back(ContactSheetThumbnail(frames[i]));
      if (!ground_truth_paths.empty()) {
        cv::Mat g;
        cv::resize(ReadImageRgb(ground_truth_paths[start + i]), g,
                   frames[i].size(), 0, 0, cv::INTER_AREA);
        gt_thumbs.push_back(ContactSheetThumbnail(g));
      }
    }
    if (a.frames) {
      WritePngSequence((fs::path(a.out) / "frames").string(), "render_", frames,
                       start);
    }
  }
  summary.mean_coverage /= std::max(1, summary.num_frames);

  // ---- Outputs ----
  if (video) {
    const VideoWriteResult written = video->Close();
    report["video"] = {
        {"path", "render.mp4"},           {"fourcc", written.fourcc},
        {"fell_back", written.fell_back}, {"fps", a.fps},
        {"width", written.width},         {"height", written.height}};
  }
  if (a.frames) report["frames_dir"] = "frames";
  if (num_frames > kMaxContactSheetFrames)
    report["contact_sheet_frames"] = kMaxContactSheetFrames;
  WriteImageRgb((fs::path(a.out) / "contact_sheet.png").string(),
                MakeContactSheet(thumbs, gt_thumbs));

  report = RenderReport(a, in, edited, preset, options,
                        !frame0_replacement.empty(), stats, summary,
                        output_size, dynamic_edit, std::move(report));
  WriteFileAtomic((fs::path(a.out) / "render.json").string(),
                  report.dump(2) + "\n");

  std::cout << a.out << ": " << num_frames << " frames " << output_size.width
            << "x" << output_size.height << " (" << ToString(options.mode)
            << ", preset " << ToString(preset)
            << ", trajectory edits: " << a.edits.Describe()
            << (dynamic ? ", objects: " + a.dynamic.edit_mode + " mode, " +
                              std::to_string(dynamic_edit["edits"].size()) +
                              " applied"
                        : std::string())
            << ") from " << cloud.size() << " points; "
            << "coverage mean " << Fixed(summary.mean_coverage, 3) << " min "
            << Fixed(summary.min_coverage, 3) << "; "
            << (a.no_video ? std::string("no video")
                           : "render.mp4 (" +
                                 report["video"]["fourcc"].get<std::string>() +
                                 (report["video"]["fell_back"].get<bool>()
                                      ? ", fallback"
                                      : "") +
                                 ")")
            << "\n";
  if (!summary.empty_frames.empty()) {
    std::cerr
        << "warning: " << summary.empty_frames.size()
        << " frame(s) have no visible point (all-invalid): see render.json\n";
  }
  return kExitOk;
}

CommandRunner SetupRender(CLI::App& app) {
  auto a = std::make_shared<RenderArgs>();
  app.add_option(
      "--cloud", a->cloud,
      "Input cloud (.ply/.pcd) in the trajectory's world frame; intrinsics "
      "from the "
      "trajectory JSON's camera or --intrinsics (K for the render size)");
  app.add_option("--image", a->image,
                 "Frame-0 image (RGB) whose depth map is --depth");
  app.add_option("--depth", a->depth,
                 "Frame-0 z-depth .npy (H, W), same size as --image");
  app.add_option("--intrinsics", a->intrinsics,
                 "K of --image: 9 numbers (pred_intrinsics.txt line or 3 "
                 "rows), integer-index "
                 "pixels");
  app.add_option("--monst3r", a->monst3r,
                 "MonST3R output folder: renders frame 0's pointmap (no "
                 "confidence threshold, as "
                 "released) along pred_traj.txt or --trajectory");
  app.add_option("--scene", a->scene,
                 "A reconstruction tool's output as TOOL:PATH (monst3r, vggt, "
                 "da3, cut3r, megasam, npz; docs/RECONSTRUCTIONS.md) or a "
                 "PATH whose format is recognised: frame 0's depth rendered "
                 "(no confidence threshold) along the tool's poses or "
                 "--trajectory");
  app.add_option(
      "--trajectory", a->trajectory,
      "Trajectory: .json (geodrive), pred_traj.txt (MonST3R, w first) or TUM "
      ".txt (w "
      "last). With --image/--monst3r it is taken relative to its first frame");
  app.add_option("--trajectory-format", a->trajectory_format,
                 "auto, json, tum, monst3r, kitti (12 numbers per line), "
                 "colmap (images.txt) or reconstruction (a tool's camera "
                 "track: .npz or folder)")
      ->check(CLI::IsMember({"auto", "json", "tum", "monst3r", "kitti",
                             "colmap", "reconstruction"}))
      ->capture_default_str();
  app.add_option(
      "--shift-left", a->edits.shift_left,
      "Shift the trajectory left by D (first camera's axes, trajectory units)");
  app.add_option("--shift-right", a->edits.shift_right, "Shift right by D");
  app.add_option("--shift-up", a->edits.shift_up, "Shift up by D");
  app.add_option("--yaw", a->edits.yaw_deg,
                 "Yaw offset in degrees (positive = turn left)");
  app.add_option("--speed", a->edits.speed_scale, "Speed scale (> 0)")
      ->capture_default_str();
  app.add_option(
      "--num-frames", a->edits.resample_frames,
      "Resample the trajectory to N frames uniformly in time (0 = keep)");
  app.add_flag(
      "--reverse", a->reverse,
      "Drive forward to the middle frame, then back (same frame count)");
  app.add_option("--mode", a->mode,
                 "zbuffer (paper) or soft (PyTorch3D); default: the preset's")
      ->check(CLI::IsMember({"zbuffer", "soft"}));
  app.add_option("--preset", a->preset,
                 "paper (zbuffer 480x720, 0.1 < z < 100), footprint (paper "
                 "with footprint-aware splats: a point seen closer than at "
                 "capture covers its magnified pixel, at most 8x) or "
                 "geodrive-compat (soft 288x512, r 0.01 NDC, K 10, x2 bilinear "
                 "upsample, frame 0 = real image)")
      ->check(CLI::IsMember({"paper", "footprint", "geodrive-compat"}))
      ->capture_default_str();
  app.add_option("--size", a->size,
                 "Render size HxW, e.g. 480x720 (default: the preset's)");
  // Values are checked where parsed: the whole string, finite, in range (no
  // silent fallback to the preset's value).
  const CLI::Validator finite_non_negative(
      [](std::string& text) -> std::string {
        double v = 0;
        if (!CLI::detail::lexical_cast(text, v) || !std::isfinite(v) || v < 0)
          return "must be a finite number >= 0, got '" + text + "'";
        return "";
      },
      "FINITE >= 0");
  const CLI::Validator finite_positive(
      [](std::string& text) -> std::string {
        double v = 0;
        if (!CLI::detail::lexical_cast(text, v) || !std::isfinite(v) || v <= 0)
          return "must be a finite number > 0, got '" + text + "'";
        return "";
      },
      "FINITE > 0");
  app.add_option_function<double>(
         "--radius", [a](double v) { a->radius = v; },
         "Splat radius: pixels in zbuffer mode (0 = one pixel), NDC units in "
         "soft mode (default: the preset's)")
      ->check(finite_non_negative);
  app.add_option_function<int>(
         "--points-per-pixel", [a](int v) { a->points_per_pixel = v; },
         "Soft mode K (1..32; default: the preset's)")
      ->check(CLI::Range(1, 32));
  app.add_option_function<double>(
         "--near", [a](double v) { a->near = v; },
         "Near depth (trajectory units, > 0; default: the preset's)")
      ->check(finite_positive);
  const CLI::Validator positive_or_inf(
      [](std::string& text) -> std::string {
        double v = 0;
        if (!CLI::detail::lexical_cast(text, v) || std::isnan(v) || v <= 0)
          return "must be a number > 0 (or inf), got '" + text + "'";
        return "";
      },
      "NUMBER > 0");
  app.add_option_function<double>(
         "--far", [a](double v) { a->far = v; },
         "Far depth (trajectory units, > 0 or inf; default: the preset's)")
      ->check(positive_or_inf);
  app.add_option_function<double>(
         "--max-magnification", [a](double v) { a->max_magnification = v; },
         "footprint preset: the largest magnification a point is drawn at "
         "(1..16; 1 = one pixel per point; default: the preset's, 8 for "
         "footprint)")
      ->check(CLI::Range(1.0, 16.0));
  app.add_flag("--hole-fill", a->hole_fill,
               "zbuffer: fill small holes from the nearest valid neighbour "
               "(off by default)");
  app.add_option(
      "--real-frame0", a->real_frame0,
      "Real frame-0 image for geodrive-compat (default: --image or MonST3R "
      "frame_0000.png)");
  app.add_option("--fps", a->fps, "Video frame rate")->capture_default_str();
  app.add_flag("--frames", a->frames,
               "Also write the lossless PNG sequence frames/render_NNNN.png");
  app.add_flag("--no-video", a->no_video, "Do not write render.mp4");
  app.add_option("--threads", a->threads,
                 "Threads (0 = all cores, at most 256)")
      ->check(ThreadCountValidator());
  app.add_option(
      "--boxes", a->dynamic.boxes_path,
      "Dynamic editing: box sequences (data_schema/boxes.schema.json)");
  app.add_option("--edit-mode", a->dynamic.edit_mode,
                 "Dynamic editing mode: 3d (segment + move in 3D) or 2d "
                 "(upstream crop-and-paste)")
      ->capture_default_str();
  app.add_option("--remove", a->dynamic.remove,
                 "Remove instance ID (repeatable; needs --boxes)");
  app.add_option("--insert", a->dynamic.insert,
                 "ID:FILE: insert a copy of ID along FILE's box sequence "
                 "(repeatable)");
  app.add_option("--move", a->dynamic.move,
                 "ID:FILE: ID follows FILE's box sequence (repeatable)");
  app.add_option("--out", a->out, "Output directory")->required();
  return [a] { return RunRender(*a); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    render,
    "render",
    "Render a conditioning video: point splatting along a trajectory",
    SetupRender);

}  // namespace geodrive
