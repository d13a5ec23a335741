// `geodrive render`: conditioning videos by point splatting along a trajectory.
//
//   geodrive render (--cloud FILE.ply | --image IMG --depth DEPTH.npy
//   --intrinsics K.txt |
//                    --monst3r DIR) --trajectory FILE [--shift-left 3]
//                    [--reverse]
//                   [--mode zbuffer|soft] [--preset paper|geodrive-compat]
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
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>

#include "apps/cli/cli.h"
#include "apps/cli/edit_args.h"
#include "dataset/scene_source.h"
#include "geometry/image_io.h"
#include "geometry/trajectory_edit.h"
#include "geometry/trajectory_json.h"
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
  std::string cloud, image, depth, intrinsics, monst3r, trajectory, out;
  std::string trajectory_format = "auto";
  std::string mode, preset = "paper", size;
  // Overrides of the preset's values (absent: the preset's).
  std::optional<double> radius;
  std::optional<int> points_per_pixel;
  std::optional<double> near, far;
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
  std::vector<cv::Mat> ground_truth;
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
    for (const std::string& path : scene.frame_image_paths)
      r.ground_truth.push_back(ReadImageRgb(path));
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

// render.json: inputs, options, camera, per-frame coverage, summary.
json RenderReport(const RenderArgs& a,
                  const RenderInput& in,
                  const Trajectory& edited,
                  RenderPreset preset,
                  const RenderOptions& options,
                  bool frame0_replaced,
                  const RenderResult& result,
                  const std::vector<cv::Mat>& frames,
                  const json& dynamic_edit,
                  json report) {
  const PinholeCamera& camera = in.camera;
  report["input"] = in.scene.description;
  report["trajectory"] =
      a.trajectory.empty() ? a.monst3r + "/pred_traj.txt" : a.trajectory;
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
  report["output_size"] = {{"width", frames[0].cols},
                           {"height", frames[0].rows}};
  json per_frame = json::array();
  for (size_t f = 0; f < result.frames.size(); ++f) {
    const RenderedFrame& fr = result.frames[f];
    per_frame.push_back({{"frame", f},
                         {"t", edited.timestamps[f]},
                         {"coverage", fr.coverage()},
                         {"valid_pixels", fr.num_valid},
                         {"filled_pixels", fr.num_filled},
                         {"points_in_view", fr.num_projected}});
  }
  report["frames"] = per_frame;
  report["summary"] = {{"mean_coverage", result.summary.mean_coverage},
                       {"min_coverage", result.summary.min_coverage},
                       {"max_coverage", result.summary.max_coverage},
                       {"all_invalid_frames", result.summary.empty_frames},
                       {"seconds", result.summary.seconds}};
  return report;
}

int RunRender(RenderArgs a) {
  const int sources = !a.cloud.empty() + !a.image.empty() + !a.monst3r.empty();
  GEODRIVE_CHECK_INPUT(
      sources == 1,
      "give exactly one input: --cloud, --image (with --depth, --intrinsics) "
      "or --monst3r");
  if (!a.image.empty()) {
    GEODRIVE_CHECK_INPUT(
        !a.depth.empty() && !a.intrinsics.empty(),
        "--image needs --depth DEPTH.npy and --intrinsics K.txt");
  }
  GEODRIVE_CHECK_INPUT(
      !a.trajectory.empty() || !a.monst3r.empty(),
      "--trajectory is required (except with --monst3r, which defaults to "
      "its pred_traj.txt)");
  const RenderPreset preset = ParseRenderPreset(a.preset);
  const RenderOptions options = RenderOptionsFromArgs(a, preset);
  a.edits.forward_then_back = a.reverse;
  a.edits.Check();

  const RenderInput in = LoadRenderInput(a, options);
  const PointCloud& cloud = in.scene.cloud;
  const PinholeCamera& camera = in.camera;
  cv::Mat real_frame0 = in.real_frame0;
  std::vector<cv::Mat> ground_truth = in.ground_truth;

  const Trajectory edited = ApplyTrajectoryEdits(in.trajectory, a.edits);
  if (edited.size() != ground_truth.size() || a.edits.Describe() != "none")
    ground_truth.clear();
  std::vector<Rigid3d> cam_from_world;
  for (const auto& pose : edited.world_from_cam)
    cam_from_world.push_back(pose.Inverse());

  // ---- Render ----
  if (!a.real_frame0.empty()) real_frame0 = ReadImageRgb(a.real_frame0);
  GEODRIVE_CHECK_INPUT(!a.dynamic.boxes_path.empty() ||
                           (a.dynamic.remove.empty() &&
                            a.dynamic.insert.empty() && a.dynamic.move.empty()),
                       "--remove/--insert/--move need --boxes FILE");
  json dynamic_edit;  // dynamic editing (render/dynamic_edit.h), with --boxes
  const RenderResult result = [&] {
    if (a.dynamic.boxes_path.empty())
      return RenderFrames(cloud, {camera}, cam_from_world, options);
    DynamicEditResult edited = ApplyEditsAndRender(
        a.dynamic, cloud, {camera}, cam_from_world, options, real_frame0);
    dynamic_edit = json::parse(edited.summary.ToJson());
    std::cout << edited.summary.BriefReport() << "\n";
    return std::move(edited).ToRenderResult();
  }();
  // Frame 0 is replaced by the real image only in the compat preset (the
  // released pipeline).
  const cv::Mat frame0_replacement =
      preset == RenderPreset::kGeodriveCompat ? real_frame0 : cv::Mat();
  const std::vector<cv::Mat> frames =
      FinalFrames(result, preset, frame0_replacement);

  // ---- Outputs ----
  std::error_code ec;
  fs::create_directories(a.out, ec);
  GEODRIVE_CHECK_INPUT(!ec, a.out, ": cannot create output directory (",
                       ec.message(), ")");
  json report;
  VideoWriteResult video;
  if (!a.no_video) {
    VideoWriteOptions vo;
    vo.fps = a.fps;
    video = WriteVideo((fs::path(a.out) / "render.mp4").string(), frames, vo);
    report["video"] = {
        {"path", "render.mp4"},         {"fourcc", video.fourcc},
        {"fell_back", video.fell_back}, {"fps", a.fps},
        {"width", video.width},         {"height", video.height}};
  }
  if (a.frames) {
    WritePngSequence((fs::path(a.out) / "frames").string(), "render_", frames);
    report["frames_dir"] = "frames";
  }
  std::vector<cv::Mat> gt_sheet;
  for (size_t i = 0; i < ground_truth.size(); ++i) {
    cv::Mat g;
    cv::resize(ground_truth[i], g, frames[i].size(), 0, 0, cv::INTER_AREA);
    gt_sheet.push_back(g);
  }
  WriteImageRgb((fs::path(a.out) / "contact_sheet.png").string(),
                MakeContactSheet(frames, gt_sheet));

  report =
      RenderReport(a, in, edited, preset, options, !frame0_replacement.empty(),
                   result, frames, dynamic_edit, std::move(report));
  {
    const std::string path = (fs::path(a.out) / "render.json").string();
    std::ofstream out(path);
    GEODRIVE_CHECK_INPUT(static_cast<bool>(out), path, ": cannot write");
    out << report.dump(2) << "\n";
  }

  std::cout << a.out << ": " << result.frames.size() << " frames "
            << frames[0].cols << "x" << frames[0].rows << " ("
            << ToString(options.mode) << ", preset " << ToString(preset)
            << ", trajectory edits: " << a.edits.Describe()
            << (a.dynamic.boxes_path.empty()
                    ? std::string()
                    : ", objects: " + a.dynamic.edit_mode + " mode, " +
                          std::to_string(dynamic_edit["edits"].size()) +
                          " applied")
            << ") from " << cloud.size() << " points; "
            << "coverage mean " << Fixed(result.summary.mean_coverage, 3)
            << " min " << Fixed(result.summary.min_coverage, 3) << "; "
            << (a.no_video ? std::string("no video")
                           : "render.mp4 (" + video.fourcc +
                                 (video.fell_back ? ", fallback" : "") + ")")
            << "\n";
  if (!result.summary.empty_frames.empty()) {
    std::cerr
        << "warning: " << result.summary.empty_frames.size()
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
  app.add_option(
      "--trajectory", a->trajectory,
      "Trajectory: .json (geodrive), pred_traj.txt (MonST3R, w first) or TUM "
      ".txt (w "
      "last). With --image/--monst3r it is taken relative to its first frame");
  app.add_option("--trajectory-format", a->trajectory_format,
                 "auto, json, tum or monst3r")
      ->check(CLI::IsMember({"auto", "json", "tum", "monst3r"}))
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
                 "paper (zbuffer 480x720, 0.1 < z < 100) or geodrive-compat "
                 "(soft 288x512, r "
                 "0.01 NDC, K 10, x2 bilinear upsample, frame 0 = real image)")
      ->check(CLI::IsMember({"paper", "geodrive-compat"}))
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
  app.add_option("--threads", a->threads, "Threads (0 = all)");
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
