// `geodrive build-dataset`: nuScenes-like clips -> condition/video training
// pairs.

#include <cstdlib>
#include <iostream>
#include <map>
#include <memory>
#include <vector>

#include "apps/cli/cli.h"
#include "dataset/build_dataset.h"
#include "dataset/drive_dataset.h"
#include "dataset/scene_source.h"
#include "geometry/util/files.h"
#include "geometry/util/progress.h"
#include "geometry/util/status.h"

#ifdef GEODRIVE_WITH_MPI
// C API only (OpenMPI would otherwise pull in its deprecated C++ bindings).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>
#endif

namespace geodrive {
namespace {

struct Args {
  BuildDatasetOptions options;
  std::string dataset = "auto";  // --dataset
  std::string shard = "0/1";
  std::string size = "480x720";
  std::string clips;
  std::string merge;
  std::string cameras;
  std::string exports = "none";
};

void ParseShard(const std::string& text, int* index, int* count) {
  const auto slash = text.find('/');
  GEODRIVE_CHECK_INPUT(slash != std::string::npos,
                       "--shard: expected i/N, got '", text, "'");
  try {
    *index = std::stoi(text.substr(0, slash));
    *count = std::stoi(text.substr(slash + 1));
  } catch (const std::exception&) {
    ThrowInputError("--shard", "expected i/N, got '", text, "'");
  }
}

bool UnderMpiLauncher() {
  return std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE") ||
         std::getenv("PMIX_RANK");
}

int Run(Args& a) {
  if (!a.merge.empty()) {
    const int n = MergeBuildOutputs(a.merge, a.options.export_options);
    std::cout << "merged " << n << " pairs into " << a.merge
              << "/manifest.jsonl; report: " << a.merge << "/report.html\n";
    return kExitOk;
  }
  BuildDatasetOptions& o = a.options;
  ParseShard(a.shard, &o.shard_index, &o.shard_count);
  if (!a.cameras.empty())
    o.cameras = ParseCameraList(a.cameras, "", "--cameras");
  o.exports = ParseExportFormats(a.exports);
  ParseSizeHxW(a.size, "--size", &o.height, &o.width);
  // The lidar-dense frame-0 depth's memory, from the option alone (a 16:9
  // camera, nuScenes' CAM_FRONT); each clip checks its own camera again.
  if (o.geometry == "lidar-dense") {
    CheckLidarDenseMemory(
        "--lidar-dense-width " + std::to_string(o.lidar_dense_width),
        o.lidar_dense_width, (int64_t{o.lidar_dense_width} * 9 + 8) / 16);
  }
  if (!a.clips.empty()) {
    std::string cur;
    for (char c : a.clips + ",") {
      if (c == ',') {
        if (!cur.empty()) o.clips.push_back(cur);
        cur.clear();
      } else {
        cur += c;
      }
    }
  }
  int rank = 0, size = 1;
  bool mpi = false;
#ifdef GEODRIVE_WITH_MPI
  if (UnderMpiLauncher()) {
    MPI_Init(nullptr, nullptr);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    mpi = true;
    GEODRIVE_CHECK_INPUT(o.shard_count == 1,
                         "--shard cannot be combined with mpirun");
    o.shard_index = rank;
    o.shard_count = size;
    if (rank != 0) o.quiet = true;
  }
#else
  if (UnderMpiLauncher() && std::getenv("OMPI_COMM_WORLD_SIZE") &&
      std::string(std::getenv("OMPI_COMM_WORLD_SIZE")) != "1") {
    ThrowInputError(
        "build-dataset",
        "started by mpirun, but this geodrive was built without MPI "
        "(configure with -DGEODRIVE_WITH_MPI=ON)");
  }
#endif
  InstallStopSignalHandlers();
  const BuildDatasetSummary s = BuildDataset(o);
  int failed = s.failed + s.log_write_errors, interrupted = s.interrupted;
#ifdef GEODRIVE_WITH_MPI
  if (mpi) {
    MPI_Allreduce(MPI_IN_PLACE, &failed, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &interrupted, 1, MPI_INT, MPI_MAX,
                  MPI_COMM_WORLD);
    if (rank == 0) MergeBuildOutputs(o.out, o.export_options);
    MPI_Barrier(MPI_COMM_WORLD);
    MPI_Finalize();
  }
#endif
  if (rank == 0) {
    std::cout << "build-dataset"
              << (mpi ? " (" + std::to_string(size) + " MPI ranks)" : "")
              << ": " << s.BriefReport() << "\n";
    if (o.shard_count == 1 || mpi) {
      std::cout << "pairs: " << o.out << "/pairs/  manifest: " << o.out
                << "/manifest.jsonl  report: " << o.out << "/report.html\n";
    } else {
      std::cout << "shard " << o.shard_index << "/" << o.shard_count
                << " done; when all shards finish run: geodrive build-dataset "
                   "--merge "
                << o.out << "\n";
    }
  }
  if (interrupted) return kExitInterrupted;
  if (failed > 0) {
    if (rank == 0) {
      std::cerr << "build-dataset: completed with failures (see " << o.out
                << "/failures.jsonl)\n";
    }
    return kExitCompletedWithFailures;
  }
  return kExitOk;
}

// Inputs and geometry: where clips come from and which scene source renders
// them.
void AddSourceOptions(CLI::App& app, BuildDatasetOptions& o) {
  app.add_option("--dataroot", o.dataroot,
                 "nuScenes root (holds <version>/, samples/, sweeps/), or a "
                 "folder of Waymo *.tfrecord segments");
  app.add_option("--version", o.version, "Table folder, e.g. v1.0-mini")
      ->capture_default_str();
  app.add_option("--monst3r", o.monst3r_root,
                 "Folder of MonST3R outputs: <clip_id>/ or "
                 "<clip_id>/reconstruction/ per clip, or the upstream "
                 "sample_%06d/ and <name>/reconstruction/ layouts through "
                 "--monst3r-map");
  app.add_option("--monst3r-map", o.monst3r_map,
                 "Folder names -> clip ids: the clips.jsonl of `geodrive "
                 "clips` (sample_%06d = its index) or '<folder> <clip id>' "
                 "lines");
  app.add_option("--out", o.out, "Output folder");
  std::vector<std::string> sources = SceneSourceNames();
  std::string source_help =
      "Scene source: monst3r (default when --monst3r is given; the MonST3R "
      "folder ROOT/<clip id>/), lidar (aggregated static LiDAR, no "
      "reconstruction needed; the default otherwise), or another registered "
      "source reading ROOT/<clip id>/:";
  for (const std::string& name : sources) source_help += " " + name;
  sources.push_back("auto");
  app.add_option("--geometry", o.geometry, source_help)
      ->check(CLI::IsMember(sources));
  app.add_option("--lidar-window", o.lidar_dense_window,
                 "lidar-dense geometry: the sweeps projected into frame 0: "
                 "causal (up to frame 0, what a car has then; default), clip "
                 "(the whole clip, denser) or explicit (0.5 s before to 1.5 s "
                 "after frame 0)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, LidarWindow>{
              {"causal", LidarWindow::kCausal},
              {"clip", LidarWindow::kClip},
              {"explicit", LidarWindow::kExplicit}},
          CLI::ignore_case))
      ->capture_default_str();
  app.add_option("--lidar-objects", o.lidar_dense_objects,
                 "lidar-dense geometry: returns inside annotated boxes: remove "
                 "(the static scene; default) or frame0 (kept from the "
                 "frame-0 sweep, so the dynamic editor moves them)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, LidarObjects>{
              {"remove", LidarObjects::kRemove},
              {"frame0", LidarObjects::kFrame0}},
          CLI::ignore_case))
      ->default_str("remove");
  app.add_option("--lidar-dense-width", o.lidar_dense_width,
                 "lidar-dense geometry: width (px) of the completed frame-0 "
                 "depth (the frame-0 camera scaled to it)")
      ->check(CLI::Range(16, 16384))
      ->capture_default_str();
}

// Which clips, and how each pair is rendered and written.
void AddPairOptions(CLI::App& app, Args& a) {
  BuildDatasetOptions& o = a.options;
  app.add_option("--clips", a.clips,
                 "Comma-separated clip ids (default: all clips)");
  app.add_option("--max-clips", o.max_clips,
                 "Stop after this many clips (0 = all)");
  app.add_option("--stride", o.clip_stride,
                 "CAM_FRONT frames between clip starts")
      ->capture_default_str();
  app.add_option("--clip-frames", o.clip_frames,
                 "Frames per clip (>= 1; one frame: a single-image pair)")
      ->capture_default_str();
  app.add_option("--frames", o.frames,
                 "Which CAM_FRONT frames make clips: all (keyframes and "
                 "sweeps, 12 Hz) or keyframes (2 Hz samples only: for "
                 "extracts without sweep files; clip ids end in _kf)")
      ->transform(
          CLI::CheckedTransformer(std::map<std::string, ClipFrameSource>{
              {"all", ClipFrameSource::kAll},
              {"keyframes", ClipFrameSource::kKeyframes}}))
      ->default_str("all");
  app.add_option(
      "--cameras", a.cameras,
      "Surround view: all (CAM_FRONT first), or CAM_A,CAM_B,... (the first "
      "is the reference: its frames make the clips). One scene per clip "
      "(lidar or lidar-dense) rendered into every camera, each along its own "
      "poses; per camera gt_<CAM>.mp4 and cond_<CAM>.mp4, a rig-layout "
      "preview.png, meta.json views and seams (docs/how-to/surround-view.md). "
      "Default: CAM_FRONT pairs");
  app.add_option("--size", a.size, "Output HxW")->capture_default_str();
  app.add_option("--resize-mode", o.resize_mode,
                 "resize (plain, GeoDrive training) or center-crop (GeoDrive "
                 "inference)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, ResizeMode>{
          {"resize", ResizeMode::kResize},
          {"center-crop", ResizeMode::kCenterCrop}}))
      ->default_str("resize");
  app.add_option(
         "--fps", o.fps,
         "Frame rate written in the videos (12 Hz clips as 10 fps, as Vista)")
      ->capture_default_str();
  app.add_option("--x264-preset", o.video_preset,
                 "x264 preset of the videos (ultrafast ... veryslow)")
      ->capture_default_str();
  app.add_option("--crf", o.video_crf,
                 "x264 constant rate factor (0 = lossless)")
      ->capture_default_str();
  app.add_flag("--lossless-frames", o.lossless_frames,
               "Also write PNG frame folders");
  app.add_option(
         "--min-confidence", o.min_confidence,
         "MonST3R confidence threshold in [0,1] (1 - 1/raw; paper tau = 0.65)")
      ->capture_default_str();
  app.add_option("--splat-radius", o.splat_radius_px,
                 "Paper preset splat radius (output px; the footprint preset "
                 "sizes every point from its capture footprint instead)")
      ->capture_default_str();
  app.add_flag("--refine-poses", o.refine_poses,
               "MonST3R geometry: refine the poses by reprojection over static "
               "confident pixels (paper eq. 3); meta.json reports the RMS "
               "before and after");
  app.add_option("--export", a.exports,
                 "Also write the pairs for other trainers, FORMAT[,FORMAT...]: "
                 "geodrive-upstream (GeoDrive's released train.py: "
                 "OUT/geodrive_upstream/sample_%06d/render_%d.png and "
                 "meta.jsonl), streetcrafter (StreetCrafter's video trainer: "
                 "OUT/streetcrafter/meta_info_{train,val}.json, 25-frame "
                 "samples at 576x320), gen3c (GEN3C's dynamic-video input: "
                 "OUT/gen3c/<clip>/rgb.mp4, depth.npz, mask.npz, camera.npz "
                 "at 1280x704; --clip-frames 121, 241, ...), rds-hq "
                 "(Cosmos-Drive-Dreams' render_from_rds_hq.py input: "
                 "OUT/rds_hq/<field>/<clip>.tar webdataset tars of poses, "
                 "intrinsics at 1280x720, LiDAR and boxes; --clip-frames 121 "
                 "or more, taken as 30 Hz), drivestudio (drivestudio's "
                 "nuScenes layout: OUT/drivestudio/%03d/ per clip, CAM_FRONT "
                 "as camera 0, with --cameras every camera under its "
                 "drivestudio index: images at 1600x900, LiDAR, sky and "
                 "dynamic masks, instances); none. Only drivestudio and "
                 "rds-hq (with --cameras all: the six cameras as "
                 "rds_hq_mv's) take --cameras")
      ->capture_default_str();
  app.add_option("--val-fraction", o.export_options.val_fraction,
                 "Exports with train/val lists (streetcrafter, rds-hq): "
                 "fraction of the scenes listed for validation (by scene, "
                 "seeded)")
      ->capture_default_str();
  app.add_option("--split-seed", o.export_options.split_seed,
                 "Seed of the exports' by-scene train/val split")
      ->capture_default_str();
  app.add_flag("--keep-mismatched", o.keep_mismatched,
               "Keep pairs of OUT built with other content options (reported) "
               "instead of rebuilding them");
  app.add_flag("--quiet", o.quiet, "No progress output");
}

CommandRunner Setup(CLI::App& app) {
  auto a = std::make_shared<Args>();
  BuildDatasetOptions& o = a->options;
  app.footer(
      "Builds one pair folder per 25-frame CAM_FRONT clip: "
      "OUT/pairs/<clip_id>/{gt.mp4, cond.mp4,\n"
      "first_frame.png, boxes.json, meta.json, preview.png}, plus "
      "OUT/manifest.jsonl,\n"
      "OUT/failures.jsonl and OUT/report.html. Reruns skip finished pairs "
      "(resume after a kill).\n"
      "Under `mpirun -n K` (built with GEODRIVE_WITH_MPI) clips are split "
      "across ranks and rank 0\n"
      "merges. Exit codes: 0 ok, 2 bad input, 3 completed with failures, 130 "
      "interrupted.");
  AddSourceOptions(app, o);
  app.add_option("--threads", o.threads, "Clips processed in parallel (1..256)")
      ->check(ThreadCountValidator() & CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--shard", a->shard,
                 "Process shard i of N (i/N), e.g. for Slurm job arrays")
      ->capture_default_str();
  app.add_option("--preset", o.preset,
                 "paper (z-buffer, one pixel per point), footprint (z-buffer, "
                 "points seen closer than at capture drawn over their "
                 "magnified footprint) or geodrive-compat (released pipeline)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, RenderPreset>{
          {"paper", RenderPreset::kPaper},
          {"footprint", RenderPreset::kFootprint},
          {"geodrive-compat", RenderPreset::kGeodriveCompat}}))
      ->default_str("paper");
  app.add_option("--remove-instance", o.remove_instances,
                 "Remove this instance (the dataset's instance id, e.g. a "
                 "nuScenes instance token; repeatable) from every condition "
                 "that has it, in every camera of a --cameras rig");
  app.add_option("--edit-mode", o.edit_mode,
                 "Dynamic editing from the clip's boxes: 3d, 2d, none")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, PairEditMode>{{"3d", PairEditMode::k3d},
                                              {"2d", PairEditMode::k2d},
                                              {"none", PairEditMode::kNone}}))
      ->default_str("3d");
  AddPairOptions(app, *a);
  app.add_option("--dataset", a->dataset,
                 "nuscenes, waymo, or auto (waymo when --dataroot holds "
                 "*.tfrecord files)")
      ->check(CLI::IsMember({"auto", "nuscenes", "waymo"}))
      ->capture_default_str();
  app.add_option("--merge", a->merge,
                 "Merge the shard outputs in this folder (manifest, failures, "
                 "the exports' indexes split by --val-fraction and "
                 "--split-seed, report) and exit");
  return [a] {
    if (a->merge.empty()) {
      GEODRIVE_CHECK_INPUT(
          !a->options.dataroot.empty() && !a->options.out.empty(),
          "build-dataset: --dataroot and --out are required (or --merge OUT)");
      a->options.dataset =
          ResolveDatasetFormat(a->dataset, a->options.dataroot);
    }
    return Run(*a);
  };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    build_dataset,
    "build-dataset",
    "Build condition/video training pairs from nuScenes-like clips",
    Setup);

}  // namespace geodrive
