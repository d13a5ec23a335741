// `geodrive-diffusion generate`: offline video generation from a first frame
// and a camera trajectory (docs/DIFFUSION.md, "generate").
//
//   1. Geometry: a point cloud from the frame-0 depth of a MonST3R folder
//      (--geometry DIR) or of --depth DEPTH.npy with --intrinsics K.txt, in the
//      camera frame of the first image.
//   2. Condition render along the trajectory (render/renderer.h; with --boxes,
//      the dynamic-object editing of render/dynamic_edit.h) at the model's
//      pixel size, padded to the model's frame count by repeating the last
//      frame (as upstream pads 25 -> 49).
//   3. VAE-encode the first image (1 frame) and the condition video (latent
//      mean x scaling_factor), sample with diffusion/sampler.h, VAE-decode.
//   4. Write the first --frames frames as MP4 (render/video.h) and a preview
//      PNG (contact sheet: condition render row above the generated row), and
//      keep the latents under <stem>_latents/.

#include <ATen/ATen.h>
#include <glog/logging.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "apps/cli/cli.h"
#include "apps/cli/edit_args.h"
#include "dataset/pairs.h"
#include "dataset/scene_source.h"
#include "diffusion/config.h"
#include "diffusion/model.h"
#include "diffusion/runtime_cli.h"
#include "diffusion/runtime_torch.h"
#include "diffusion/safetensors.h"
#include "diffusion/sampler.h"
#include "diffusion/vae.h"
#include "geometry/camera.h"
#include "geometry/image_io.h"
#include "geometry/npy.h"
#include "geometry/point_cloud.h"
#include "geometry/trajectory.h"
#include "geometry/trajectory_json.h"
#include "geometry/util/files.h"
#include "geometry/util/output_file.h"
#include "geometry/util/progress.h"
#include "geometry/util/status.h"
#include "render/dynamic_edit.h"
#include "render/presets.h"
#include "render/renderer.h"
#include "render/video/video.h"
#include "render/video/video_io.h"

namespace geodrive {
namespace diffusion {
namespace {

namespace fs = std::filesystem;

struct GenerateArgs {
  std::string image, trajectory, boxes, edit_mode = "3d", geometry, depth,
                                        intrinsics, scene;
  std::string config = "tiny", weights, branch_weights, vae_weights,
              prompt_embeds;
  std::string out, preset = "paper", scheduler = "dpm";
  std::string manifest, out_dir;  // batch mode over build-dataset pairs
  // A ready condition video (e.g. `geodrive plan --videos`): no render.
  std::string condition;
  int limit = 0;   // batch mode: at most this many pairs (0: all)
  int frames = 0;  // 0: min(model frames, trajectory poses)
  int steps = 50;
  uint64_t seed = 0;
  double guidance = 6.0, conditioning_scale = 1.0, fps = 8.0;
  bool dynamic_cfg = false, no_progress = false;
  RuntimeArgs runtime;  // --device, --dtype, --vae-dtype, --attention, ...
};

// RGB uint8 frames -> [1, 3, F, H, W] float32 in [-1, 1].
at::Tensor FramesToTensor(const std::vector<cv::Mat>& frames) {
  std::vector<at::Tensor> ts;
  for (const cv::Mat& f : frames) {
    const cv::Mat c = f.isContinuous() ? f : f.clone();
    ts.push_back(at::from_blob(c.data, {c.rows, c.cols, 3}, at::kByte)
                     .to(at::kFloat)
                     .permute({2, 0, 1}));
  }
  return (at::stack(ts, 1).unsqueeze(0) / 127.5 - 1.0).contiguous();
}

// [1, 3, F, H, W] in about [-1, 1] -> the first `count` RGB uint8 frames.
std::vector<cv::Mat> TensorToFrames(const at::Tensor& video, int count) {
  const at::Tensor u8 = ((video.clamp(-1.0, 1.0) + 1.0) * 127.5)
                            .round()
                            .to(at::kByte)
                            .permute({0, 2, 3, 4, 1})
                            .contiguous();
  std::vector<cv::Mat> out;
  const int h = static_cast<int>(u8.size(2)), w = static_cast<int>(u8.size(3));
  for (int f = 0; f < count; ++f) {
    cv::Mat m(h, w, CV_8UC3);
    std::memcpy(m.data, u8[0][f].data_ptr<uint8_t>(), size_t(h) * w * 3);
    out.push_back(m);
  }
  return out;
}

// The model's clip geometry: frames and pixel size of one generation.
struct Model {
  DiTConfig dit;
  VaeConfig vc;
  int model_frames = 0, H = 0, W = 0;
  RuntimeOptions runtime;
  AttentionBackend attention = AttentionBackend::kAuto;
};

Model LoadModel(const GenerateArgs& a) {
  Model m;
  m.dit = ConfigPreset(a.config);
  m.dit.Check();
  m.vc = VaePreset(a.config);
  m.vc.Check();
  GEODRIVE_CHECK_INPUT(m.vc.latent_channels == m.dit.out_channels, "--config ",
                       a.config, ": VAE latent channels ", m.vc.latent_channels,
                       " != transformer channels ", m.dit.out_channels);
  m.model_frames = static_cast<int>(m.vc.PixelFrames(m.dit.latent_frames));
  m.H = m.dit.latent_height * m.vc.spatial_compression;
  m.W = m.dit.latent_width * m.vc.spatial_compression;
  GEODRIVE_CHECK_INPUT(!a.weights.empty(), "--weights is required");
  GEODRIVE_CHECK_INPUT(std::isfinite(a.fps) && a.fps > 0 && a.fps <= 1000,
                       "--fps must be in (0, 1000]");
  GEODRIVE_CHECK_INPUT(std::isfinite(a.conditioning_scale),
                       "--conditioning-scale must be finite");
  // The sampler's options are checked here, before any rendering or
  // encoding (the sampler checks them again when it runs).
  SampleOptions probe;
  probe.weights = a.weights;
  probe.latents = probe.cond_latents = probe.out = "(written later)";
  probe.scheduler = a.scheduler;
  probe.steps = a.steps;
  probe.guidance = a.guidance;
  probe.Check();
  m.runtime = a.runtime.Parse();
  m.attention = a.runtime.Attention();
  return m;
}

// The VAE on the compute device in --vae-dtype.
Weights LoadVae(const GenerateArgs& a, const Model& m) {
  const VaeConfig& vc = m.vc;
  WeightPlacement placement;
  placement.device = m.runtime.device;
  placement.dtype = m.runtime.vae_dtype;
  if (a.vae_weights.empty()) {
    GEODRIVE_CHECK_INPUT(vc.name == "tiny", "--config ", a.config,
                         " needs --vae-weights (diffusers vae/"
                         "diffusion_pytorch_model.safetensors)");
    return VaeInitWeights(vc, a.seed)
        .To(ComputeOptions(placement.device, placement.dtype));
  }
  LoadReport report;
  return LoadWeights(a.vae_weights, VaeParamSpecs(vc), "", true, &report,
                     placement);
}

// Encodes the first image and the condition frames (resized to the model size,
// the first `frames` used, padded to the model frame count by repeating the
// last), samples, decodes and writes the first `frames` frames to `out`, a
// contact sheet (condition row above generated row) to `preview` and the
// latents to `work`/{image,cond,sample}.safetensors. Returns a summary.
std::string GenerateVideo(const GenerateArgs& a,
                          const Model& m,
                          const Weights& vae,
                          const cv::Mat& image,
                          const std::vector<cv::Mat>& cond_frames,
                          int frames,
                          const std::string& out,
                          const std::string& preview,
                          const fs::path& work) {
  const int W = m.W, H = m.H;
  const VaeConfig& vc = m.vc;
  std::vector<cv::Mat> cond;
  for (int i = 0; i < frames; ++i) {
    const cv::Mat& f = cond_frames[i];
    cond.push_back(f.cols == W && f.rows == H ? f : ResizeBilinear(f, W, H));
  }
  std::vector<cv::Mat> cond_padded = cond;
  while (static_cast<int>(cond_padded.size()) < m.model_frames)
    cond_padded.push_back(cond.back());
  const cv::Mat first = (image.cols == W && image.rows == H)
                            ? image
                            : ResizeBilinear(image, W, H);

  // ---- VAE encode ----
  std::error_code ec;
  fs::create_directories(work, ec);
  GEODRIVE_CHECK_INPUT(!ec, work.string(), ": cannot create directory (",
                       ec.message(), ")");
  const double sf = vc.scaling_factor;
  {
    at::NoGradGuard no_grad;
    // Latent mean (upstream samples the posterior; the mean is deterministic)
    // x scaling_factor, as [B, F, C, h, w] for the transformer.
    const at::Tensor image_lat =
        (VaeEncode(vc, vae, FramesToTensor({first})).to(at::kFloat).cpu() * sf)
            .permute({0, 2, 1, 3, 4})
            .contiguous();
    const at::Tensor cond_lat =
        (VaeEncode(vc, vae, FramesToTensor(cond_padded)).to(at::kFloat).cpu() *
         sf)
            .permute({0, 2, 1, 3, 4})
            .contiguous();
    SaveSafetensors((work / "image.safetensors").string(),
                    {{"latents", image_lat}});
    SaveSafetensors((work / "cond.safetensors").string(),
                    {{"latents", cond_lat}});
  }

  // ---- Sample ----
  SampleOptions so;
  so.config = a.config;
  so.weights = a.weights;
  so.branch_weights = a.branch_weights;
  so.latents = (work / "image.safetensors").string();
  so.cond_latents = (work / "cond.safetensors").string();
  so.prompt_embeds = a.prompt_embeds;
  so.out = (work / "sample.safetensors").string();
  so.scheduler = a.scheduler;
  so.steps = a.steps;
  so.seed = a.seed;
  so.guidance = a.guidance;
  so.dynamic_cfg = a.dynamic_cfg;
  so.conditioning_scale = a.conditioning_scale;
  so.progress = !a.no_progress;
  so.runtime = m.runtime;
  so.attention = m.attention;
  so.Check();
  const SampleResult sr = Sample(so);

  // ---- Decode and write ----
  at::Tensor sample;
  for (auto& [name, t] : LoadSafetensors(so.out)) {
    if (name == "latents") sample = t;
  }
  CHECK(sample.defined()) << so.out << " has no 'latents'";
  std::vector<cv::Mat> video_frames;
  {
    at::NoGradGuard no_grad;
    const at::Tensor z =
        (sample.to(at::kFloat) / sf).permute({0, 2, 1, 3, 4}).contiguous();
    video_frames =
        TensorToFrames(VaeDecode(vc, vae, z).to(at::kFloat).cpu(), frames);
  }
  VideoWriteOptions vo;
  vo.fps = a.fps;
  {
    std::error_code dir_ec;
    const fs::path parent = fs::path(out).parent_path();
    if (!parent.empty()) fs::create_directories(parent, dir_ec);
  }
  const VideoWriteResult vw = WriteVideo(out, video_frames, vo);
  WriteImageRgb(preview, MakeContactSheet(video_frames, cond));
  std::ostringstream summary;
  summary << out << ": " << frames << " frames " << W << "x" << H << " ("
          << vw.fourcc << (vw.fell_back ? ", fallback" : "") << "), config "
          << a.config << ", " << sr.steps << " " << a.scheduler << " steps in "
          << std::fixed << std::setprecision(1) << sr.seconds << " s; preview "
          << preview << "; latents " << work.string() << "/";
  return summary.str();
}

// Batch generation over a build-dataset manifest: the first GT frame and the
// condition video of each pair -> <out-dir>/<clip_id>.mp4 (the layout
// `geodrive eval` reads as predictions); previews and latents go to
// <out-dir>_work/<clip_id>/ so that <out-dir> holds only videos.
int RunGenerateManifest(const GenerateArgs& a) {
  GEODRIVE_CHECK_INPUT(
      a.geometry.empty() && a.depth.empty() && a.scene.empty() &&
          a.image.empty() && a.trajectory.empty() && a.boxes.empty() &&
          a.out.empty(),
      "--manifest reads the first frame and condition video of each pair; "
      "do not combine it with --geometry, --scene, --depth, --image, "
      "--trajectory, "
      "--boxes or --out");
  GEODRIVE_CHECK_INPUT(!a.out_dir.empty(), "--manifest needs --out-dir");
  GEODRIVE_CHECK_INPUT(a.limit >= 0, "--limit must be >= 0");
  GEODRIVE_CHECK_INPUT(a.frames >= 0, "--frames must be >= 0");
  // Every option and both output folders are checked before any work.
  const Model m = LoadModel(a);
  const fs::path out_dir(a.out_dir);
  const fs::path work_root(a.out_dir + "_work");
  CreateOutputDirectory(out_dir.string());
  CreateOutputDirectory(work_root.string());
  const std::vector<ManifestEntry> entries = ReadManifest(a.manifest);
  GEODRIVE_CHECK_INPUT(!entries.empty(), a.manifest, ": no pairs");
  const fs::path manifest_path(a.manifest);
  const std::string build_dir = manifest_path.has_parent_path()
                                    ? manifest_path.parent_path().string()
                                    : std::string(".");
  const Weights vae = LoadVae(a, m);
  // The builder's batch contract: a bad pair is recorded in
  // <out-dir>/failures.jsonl (clip, stage, error), the rest are generated,
  // and the run exits 3 when any failed.
  const std::string failures_path = (out_dir / "failures.jsonl").string();
  WriteFileAtomic(failures_path, "");
  JsonlAppender failures(failures_path);
  int done = 0, failed = 0;
  for (const ManifestEntry& e : entries) {
    if (a.limit > 0 && done + failed >= a.limit) break;
    if (StopRequested()) break;
    std::string stage = "read pair";
    try {
      const PairRecord rec = ReadPair(build_dir, e);
      const std::vector<cv::Mat> gt = ReadVideoFrames(rec.gt_video);
      const std::vector<cv::Mat> cond = ReadVideoFrames(rec.cond_video);
      GEODRIVE_CHECK_INPUT(!gt.empty(), rec.gt_video, ": no frames");
      const int avail = static_cast<int>(cond.size());
      const int frames =
          a.frames > 0 ? a.frames : std::min(m.model_frames, avail);
      GEODRIVE_CHECK_INPUT(
          frames >= 1 && frames <= m.model_frames && frames <= avail,
          rec.cond_video, ": ", avail, " condition frames; --frames ", frames,
          " must be in [1, min(", m.model_frames, ", ", avail, ")]");
      stage = "generate";
      std::cout << GenerateVideo(
                       a, m, vae, gt[0], cond, frames,
                       (out_dir / (e.clip_id + ".mp4")).string(),
                       (work_root / e.clip_id / "preview.png").string(),
                       work_root / e.clip_id)
                << std::endl;
      ++done;
    } catch (const std::bad_alloc&) {
      throw;  // out of memory: the whole run stops (the ladder's line)
    } catch (const std::exception& e_what) {
      ++failed;
      FailureEntry f;
      f.clip_id = e.clip_id;
      f.stage = stage;
      f.error = FirstLineOf(e_what.what());
      failures.Append(FailureEntryToJson(f));
      std::cerr << "generate: " << e.clip_id << " failed (" << stage
                << "): " << f.error << std::endl;
    }
  }
  std::cout << a.out_dir << ": " << done << " video(s) from " << a.manifest;
  if (failed > 0)
    std::cout << ", " << failed << " failed (" << failures_path << ")";
  std::cout << std::endl;
  if (StopRequested()) return kExitInterrupted;
  return failed > 0 ? kExitCompletedWithFailures : kExitOk;
}

// GenerateVideo into --out, its preview and latents beside it
// (<stem>_preview.png, <stem>_latents/); returns its summary.
std::string GenerateToOut(const GenerateArgs& a,
                          const Model& m,
                          const cv::Mat& image,
                          const std::vector<cv::Mat>& cond,
                          int frames) {
  const fs::path out_path(a.out);
  const fs::path dir =
      out_path.has_parent_path() ? out_path.parent_path() : fs::path(".");
  const std::string stem = out_path.stem().string();
  const Weights vae = LoadVae(a, m);
  return GenerateVideo(a, m, vae, image, cond, frames, a.out,
                       (dir / (stem + "_preview.png")).string(),
                       dir / (stem + "_latents"));
}

// From a first frame and a condition video made elsewhere (`geodrive plan
// --videos`, a pair's cond.mp4): its first --frames frames (default: as many
// as the model takes) condition the sample; nothing is rendered.
int RunGenerateFromCondition(const GenerateArgs& a) {
  GEODRIVE_CHECK_INPUT(!a.out.empty(), "--out is required");
  GEODRIVE_CHECK_INPUT(!a.image.empty(), "--condition needs --image");
  GEODRIVE_CHECK_INPUT(
      a.geometry.empty() && a.scene.empty() && a.depth.empty() &&
          a.trajectory.empty() && a.boxes.empty(),
      "--condition takes a rendered condition video: --geometry, --scene, "
      "--depth, --trajectory and --boxes do not apply");
  CheckOutputIsNotInput(
      a.out, {a.image, a.condition, a.weights, a.branch_weights, a.vae_weights,
              a.prompt_embeds});
  const Model m = LoadModel(a);
  const cv::Mat image = ReadImageRgb(a.image);
  const std::vector<cv::Mat> cond = ReadVideoFrames(a.condition);
  const int avail = static_cast<int>(cond.size());
  const int frames = a.frames > 0 ? a.frames : std::min(m.model_frames, avail);
  GEODRIVE_CHECK_INPUT(frames >= 1 && frames <= m.model_frames, "--frames ",
                       frames, " must be in [1, ", m.model_frames,
                       "]: config '", a.config, "' generates ", m.model_frames,
                       " frames at ", m.W, "x", m.H);
  GEODRIVE_CHECK_INPUT(avail >= frames, a.condition, ": ", avail,
                       " condition frames; --frames ", frames);
  std::cout << GenerateToOut(a, m, image, cond, frames) << "; condition video "
            << a.condition << std::endl;
  return 0;
}

int RunGenerate(const GenerateArgs& a) {
  if (!a.manifest.empty()) return RunGenerateManifest(a);
  if (!a.condition.empty()) return RunGenerateFromCondition(a);
  GEODRIVE_CHECK_INPUT(!a.out.empty(), "--out is required");
  // The video is not written over (or into the folder of) an input.
  const size_t colon = a.scene.find(':');
  CheckOutputIsNotInput(
      a.out,
      {a.geometry, a.depth, a.image, a.intrinsics, a.trajectory, a.boxes,
       a.weights, a.branch_weights, a.vae_weights, a.prompt_embeds,
       colon == std::string::npos ? a.scene : a.scene.substr(colon + 1)});
  const Model m = LoadModel(a);
  const int model_frames = m.model_frames, H = m.H, W = m.W;
  GEODRIVE_CHECK_INPUT(
      !a.geometry.empty() + !a.depth.empty() + !a.scene.empty() == 1,
      "give exactly one of --geometry MONST3R_DIR, --scene TOOL:PATH and "
      "--depth DEPTH.npy");
  const RenderPreset preset = ParseRenderPreset(a.preset);

  // ---- Geometry, first image, trajectory (dataset/scene_source.h) ----
  Trajectory trajectory;
  std::string traj_desc = a.trajectory;
  if (!a.trajectory.empty()) {
    trajectory = ReadTrajectoryAny(a.trajectory);
    trajectory.Check(a.trajectory);
  }
  SceneInputs in;
  in.image_path = a.image;
  std::string source = "monst3r";
  if (!a.geometry.empty()) {
    in.path = a.geometry;
  } else if (!a.scene.empty()) {
    std::tie(source, in.path) = ParseSceneArgument(a.scene);
  } else {
    GEODRIVE_CHECK_INPUT(
        !a.image.empty() && !a.intrinsics.empty() && !a.trajectory.empty(),
        "--depth needs --image, --intrinsics and "
        "--trajectory");
    source = "image-depth";
    in.path = a.depth;
    in.intrinsics_path = a.intrinsics;
  }
  SceneSourceOptions scene_options;
  scene_options.filter = PointmapFilter::kReleased;  // as the released scripts
  const ConditionScene scene = BuildConditionScene(source, in, scene_options);
  const PointCloud& cloud = scene.cloud;
  const PinholeCamera& camera = scene.camera;
  const cv::Mat& image = scene.frame0_rgb;
  if (a.trajectory.empty()) {
    trajectory = scene.trajectory;
    traj_desc = !a.scene.empty() ? a.scene + " (its camera poses)"
                                 : a.geometry + "/pred_traj.txt";
  } else {
    trajectory = scene.PlaceTrajectory(trajectory);
  }
  GEODRIVE_CHECK_INPUT(!cloud.empty(), "geometry has no valid depth");
  const int frames =
      a.frames > 0
          ? a.frames
          : std::min(model_frames, static_cast<int>(trajectory.size()));
  GEODRIVE_CHECK_INPUT(frames >= 1 && frames <= model_frames, "--frames ",
                       frames, " must be in [1, ", model_frames, "]: config '",
                       a.config, "' generates ", model_frames, " frames at ", W,
                       "x", H);
  GEODRIVE_CHECK_INPUT(static_cast<int>(trajectory.size()) >= frames, traj_desc,
                       ": ", trajectory.size(), " poses, fewer than the ",
                       frames, " frames asked for");

  // ---- Condition render ----
  std::vector<Rigid3d> cam_from_world;
  for (int i = 0; i < frames; ++i)
    cam_from_world.push_back(trajectory.world_from_cam[i].Inverse());
  RenderOptions ro = PresetRenderOptions(preset);
  const int up = PresetUpsampleFactor(preset);
  GEODRIVE_CHECK_INPUT(W % up == 0 && H % up == 0, "--preset ", a.preset,
                       ": model size ", W, "x", H, " not divisible by ", up);
  ro.width = W / up;
  ro.height = H / up;
  if (ro.mode == RenderMode::kSoft) ro.output_float_rgb = true;
  ro.Check();
  RenderResult rendered;
  if (a.boxes.empty()) {
    rendered = RenderFrames(cloud, {camera}, cam_from_world, ro);
  } else {
    EditCliArgs edit;
    edit.boxes_path = a.boxes;
    edit.edit_mode = a.edit_mode;
    DynamicEditResult r =
        ApplyEditsAndRender(edit, cloud, {camera}, cam_from_world, ro, image);
    std::cerr << r.summary.BriefReport() << "\n";
    rendered = std::move(r).ToRenderResult();
  }
  std::vector<cv::Mat> cond =
      FinalFrames(rendered, preset,
                  preset == RenderPreset::kGeodriveCompat ? image : cv::Mat());
  std::cout << GenerateToOut(a, m, image, cond, frames)
            << "; condition render from " << cloud.size()
            << " points, mean coverage " << std::fixed << std::setprecision(3)
            << rendered.summary.mean_coverage << std::endl;
  return 0;
}

}  // namespace

// The `generate` subcommand of geodrive-diffusion.
CommandRunner SetupGenerate(CLI::App& sub) {
  auto a = std::make_shared<GenerateArgs>();
  CLI::App* g = &sub;
  g->add_option("--image", a->image,
                "first frame (RGB image; with --geometry the default is the "
                "folder's frame_0000.png)");
  g->add_option("--trajectory", a->trajectory,
                "camera trajectory (JSON, TUM or pred_traj.txt), taken "
                "relative to its first pose (default with --geometry: the "
                "folder's pred_traj.txt)");
  g->add_option(
      "--boxes", a->boxes,
      "boxes JSON: dynamic objects rendered along their box tracks "
      "(render/dynamic_edit.h); its num_frames must equal the frame count");
  g->add_option("--edit-mode", a->edit_mode, "dynamic editing: 3d or 2d")
      ->capture_default_str();
  g->add_option("--geometry", a->geometry,
                "MonST3R output folder (frame-0 depth, intrinsics, poses)");
  g->add_option("--scene", a->scene,
                "another reconstruction tool's output as TOOL:PATH (vggt, "
                "da3, cut3r, megasam, moge, npz, monst3r) or a detected PATH "
                "(docs/RECONSTRUCTIONS.md), instead of --geometry");
  g->add_option("--depth", a->depth,
                "frame-0 depth .npy (H, W) of --image (instead of --geometry)");
  g->add_option("--intrinsics", a->intrinsics, "K.txt for --depth");
  g->add_option("--config", a->config, "preset: tiny or cogvideox-5b-i2v")
      ->capture_default_str();
  g->add_option("--weights", a->weights,
                "backbone checkpoint (.safetensors or .index.json; an "
                "init-weights file also holds the encoder)")
      ->required();
  g->add_option("--branch-weights", a->branch_weights,
                "encoder checkpoint (default: see `sample --help`)");
  g->add_option("--vae-weights", a->vae_weights,
                "VAE checkpoint (diffusers vae/diffusion_pytorch_model."
                "safetensors); default with --config tiny: random VAE from "
                "--seed (tests only)");
  g->add_option("--prompt-embeds", a->prompt_embeds,
                "prompt embeddings safetensors (see `sample --help`)");
  g->add_option("--frames", a->frames,
                "output frames (<= the model's 1 + 4(F'-1); default: min of "
                "that and the trajectory length)");
  g->add_option("--out", a->out,
                "output video.mp4 (also writes <stem>_preview.png and "
                "<stem>_latents/)");
  g->add_option("--manifest", a->manifest,
                "batch mode: build-dataset manifest.jsonl; one video per pair "
                "from its first GT frame and condition video");
  g->add_option("--condition", a->condition,
                "a rendered condition video (e.g. geodrive plan --videos) with "
                "--image: generate from it instead of rendering one");
  g->add_option("--out-dir", a->out_dir,
                "batch mode: folder of <clip_id>.mp4 (for `geodrive eval`); "
                "previews and latents go to <out-dir>_work/");
  g->add_option("--limit", a->limit, "batch mode: at most N pairs (0: all)")
      ->capture_default_str();
  g->add_option("--preset", a->preset,
                "condition render preset: paper, footprint or geodrive-compat")
      ->capture_default_str();
  g->add_option("--steps", a->steps, "inference steps")->capture_default_str();
  g->add_option("--seed", a->seed, "noise seed")->capture_default_str();
  g->add_option("--scheduler", a->scheduler, "dpm or ddim")
      ->capture_default_str();
  g->add_option("--guidance", a->guidance, "classifier-free guidance scale")
      ->capture_default_str();
  g->add_flag("--dynamic-cfg", a->dynamic_cfg, "CogVideoX dynamic guidance");
  g->add_option("--conditioning-scale", a->conditioning_scale,
                "encoder output scale")
      ->capture_default_str();
  g->add_option("--fps", a->fps, "video frame rate")->capture_default_str();
  g->add_flag("--no-progress", a->no_progress, "no progress bar");
  AddRuntimeOptions(*g, &a->runtime,
                    kRuntimeVae | kRuntimeAttention | kRuntimeOffload);
  return [a] { return RunGenerate(*a); };
}

GEODRIVE_REGISTER_COMMAND(
    generate,
    "generate",
    "Generate a video from a first frame and a trajectory: condition render, "
    "VAE encode, sample, VAE decode; writes MP4 + preview PNG",
    SetupGenerate);

}  // namespace diffusion
}  // namespace geodrive
