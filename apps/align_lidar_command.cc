// `geodrive align-lidar`: metric depth scale of a MonST3R clip from LiDAR, and
// the metric trajectory.

#include <filesystem>
#include <iostream>
#include <memory>

#include "apps/cli/cli.h"
#include "dataset/drive_dataset.h"
#include "dataset/lidar_alignment.h"
#include "geometry/image_io.h"
#include "geometry/monst3r.h"
#include "geometry/trajectory_io.h"
#include "geometry/util/files.h"
#include "geometry/util/progress.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

struct AlignArgs {
  std::string dataroot, version = "v1.0-mini", clip, monst3r, out;
  std::string sweep = "nearest";
  double max_gap_ms = 50;
  std::string alignment = "se3";
  int stride = 6;
};

int Run(const AlignArgs& a) {
  CreateOutputDirectory(a.out);  // an unusable --out fails before the fit
  DriveDatasetOptions dso;
  dso.root = a.dataroot;
  dso.version = a.version;
  dso.clip_stride = 1;  // every start: any clip id of any stride resolves
  const std::unique_ptr<DriveDataset> dataset = OpenDriveDataset(dso);
  DriveClip clip;
  try {
    clip = dataset->LoadClip(a.clip);
  } catch (const InputError& e) {
    ThrowInputError("--clip", e.what());
  }
  const Monst3rFolder folder = Monst3rFolder::Open(a.monst3r);
  LidarScaleOptions options;
  options.sweep = a.sweep == "keyframe" ? LidarSweepChoice::kKeyframe
                                        : LidarSweepChoice::kNearest;
  options.max_time_gap_s = a.max_gap_ms * 1e-3;
  options.alignment = ParseAlignmentType(a.alignment);
  const ClipScaleReport report = FitClipLidarScale(clip, folder, options);
  WriteFileAtomic(a.out + "/report.json", ClipScaleReportToJson(report));
  // The residual picture of the frame with the most LiDAR samples.
  int best = -1;
  size_t most = 0;
  for (const auto& f : report.frames) {
    if (f.samples.size() > most) most = f.samples.size(), best = f.frame;
  }
  if (best >= 0) {
    const Monst3rFrame frame = folder.LoadFrame(best);
    WriteImageRgb(
        a.out + "/residuals.png",
        DrawScaleResiduals(frame, report.frames[best],
                           report.success ? report.clip_fit.scale
                                          : report.frames[best].fit.scale));
  }
  if (!report.success) {
    std::cerr << "align-lidar: " << report.message << " (see " << a.out
              << "/report.json)\n";
    return kExitBadInput;
  }
  WriteTumTrajectory(a.out + "/trajectory_metric.tum", report.scaled_monst3r);
  WriteTumTrajectory(a.out + "/trajectory_aligned.tum", report.aligned_monst3r);
  WriteTumTrajectory(a.out + "/trajectory_ego.tum", report.metric_reference);
  WriteFileAtomic(a.out + "/scale.json",
                  "{\"clip_id\": \"" + a.clip +
                      "\", \"metres_per_monst3r_unit\": " +
                      std::to_string(report.clip_fit.scale) + "}\n");
  std::cout
      << "align-lidar " << a.clip << ": " << report.BriefReport() << "\n"
      << "wrote " << a.out
      << "/{report.json, scale.json, residuals.png, trajectory_metric.tum, "
         "trajectory_aligned.tum, trajectory_ego.tum} (TUM: t x y z qx qy qz "
         "qw, metres, "
         "first camera frame)\n";
  return kExitOk;
}

CommandRunner SetupAlignLidar(CLI::App& app) {
  auto a = std::make_shared<AlignArgs>();
  app.footer(
      "Projects each frame's nearest LiDAR sweep into the camera (full "
      "nuScenes chain), samples\n"
      "the MonST3R depth there (bilinear, skipping invalid and dynamic pixels) "
      "and fits\n"
      "d_lidar = s * d_monst3r robustly (RANSAC + IRLS on log ratios). The "
      "scaled MonST3R\n"
      "trajectory is aligned to the ego-pose camera trajectory (Umeyama) and "
      "ATE/RPE reported in\n"
      "metres (evo conventions).");
  app.add_option("--dataroot", a->dataroot, "nuScenes root")->required();
  app.add_option("--version", a->version, "Table folder")
      ->capture_default_str();
  app.add_option("--clip", a->clip, "Clip id, e.g. scene-0001_0024")
      ->required();
  app.add_option("--monst3r", a->monst3r, "The clip's MonST3R folder")
      ->required();
  app.add_option("--out", a->out, "Output folder")->required();
  app.add_option("--sweep", a->sweep,
                 "nearest or keyframe LiDAR sweep per frame")
      ->check(CLI::IsMember({"nearest", "keyframe"}))
      ->capture_default_str();
  app.add_option("--max-gap-ms", a->max_gap_ms, "Max camera-LiDAR time gap")
      ->capture_default_str();
  app.add_option("--align", a->alignment,
                 "Trajectory alignment: none, se3, sim3, scale")
      ->check(CLI::IsMember({"none", "se3", "sim3", "scale"}))
      ->capture_default_str();
  return [a] { return Run(*a); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    align_lidar,
    "align-lidar",
    "Metric depth scale and trajectory of a MonST3R clip from LiDAR",
    SetupAlignLidar);

}  // namespace geodrive
