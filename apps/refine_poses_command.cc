// `geodrive refine-poses --monst3r DIR --out traj.txt`: Ceres pose refinement
// over static, confident pixels (GeoDrive eq. 3), writing the refined
// trajectory and a JSON summary per frame.

#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "apps/cli/cli.h"
#include "geometry/monst3r.h"
#include "geometry/pointmap.h"
#include "geometry/pose_refinement.h"
#include "geometry/trajectory_io.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

struct RefineArgs {
  std::string monst3r, out, format = "auto", summary, frames = "all",
                            loss = "huber", mask = "enlarged";
  bool joint = false, all_pixels = false;
  PoseRefinementOptions options;
  PointmapFilterOptions filter;
};

int RunRefine(RefineArgs a) {
  a.options.loss = ParseRobustLoss(a.loss);
  a.options.Check();
  a.filter.selection =
      a.all_pixels ? PixelSelection::kAll : PixelSelection::kStaticOnly;
  a.filter.mask_kind =
      a.mask == "plain" ? DynamicMaskKind::kPlain : DynamicMaskKind::kEnlarged;
  a.filter.Check();
  const Monst3rFolder folder = Monst3rFolder::Open(a.monst3r);
  // No command writes over its own inputs: the outputs may not be a file of
  // the folder it reads (pred_traj.txt above all).
  const std::string summary_out =
      a.summary.empty() ? a.out + ".json" : a.summary;
  for (const std::string& out : {a.out, summary_out})
    CheckOutputFileOutsideInput(out, a.monst3r);
  const std::vector<int> frames = ParseFrameList(a.frames, folder.num_frames());
  if (!folder.has_raw_pointmaps()) {
    std::cerr << "note: " << a.monst3r
              << " has no pts3d_{i}.npy pointmaps; O_t is built from depth and "
                 "the stored pose, "
                 "so the refinement checks consistency (and the focal with "
                 "--refine-focal)\n";
  }
  const std::vector<PoseRefinementInput> inputs =
      PoseRefinementInputs(folder, frames, a.filter);
  const auto results = RefineClipPoses(inputs, a.options, a.joint);

  Trajectory refined;
  nlohmann::json summary = nlohmann::json::array();
  int skipped = 0;
  for (size_t k = 0; k < results.size(); ++k) {
    const auto& r = results[k];
    const auto& s = r.summary;
    refined.Add(folder.trajectory().timestamps[frames[k]], r.world_from_cam);
    skipped += s.skipped;
    summary.push_back({{"frame", s.frame_index},
                       {"skipped", s.skipped},
                       {"skip_reason", s.skip_reason},
                       {"initialization", s.initialization},
                       {"valid_pixels", s.num_valid_pixels},
                       {"residuals", s.num_residuals},
                       {"inliers", s.num_inliers},
                       {"initial_rms_px", s.initial_rms_px},
                       {"final_rms_px", s.final_rms_px},
                       {"initial_median_px", s.initial_median_px},
                       {"final_median_px", s.final_median_px},
                       {"final_inlier_rms_px", s.final_inlier_rms_px},
                       {"focal_scale", s.final_focal_scale},
                       {"fx", r.camera.fx},
                       {"fy", r.camera.fy},
                       {"iterations", s.iterations},
                       {"termination", s.termination},
                       {"usable", s.usable},
                       {"seconds", s.seconds}});
    std::cout << s.BriefReport() << "\n";
  }
  std::string format = a.format;
  if (format == "auto") format = EndsWith(a.out, ".tum") ? "tum" : "monst3r";
  if (format == "tum") {
    WriteTumTrajectory(a.out, refined);
  } else {
    WriteMonst3rTrajectory(a.out, refined);
  }
  const std::string summary_path =
      a.summary.empty() ? a.out + ".json" : a.summary;
  {
    nlohmann::json doc = {
        {"monst3r", a.monst3r},
        {"trajectory", a.out},
        {"format", format == "tum" ? "tum (t x y z qx qy qz qw), world_from_cam"
                                   : "monst3r (t x y z qw qx qy qz), "
                                     "world_from_cam"},
        {"units", "MonST3R units"},
        {"joint", a.joint},
        {"loss", a.loss},
        {"loss_scale_px", a.options.loss_scale_px},
        {"pointmaps", folder.has_raw_pointmaps() ? "pts3d" : "depth+pose"},
        {"frames", summary}};
    WriteFileAtomic(summary_path, doc.dump(2) + "\n");
  }
  std::cout << a.out << ": " << refined.size() << " poses (" << format << "), "
            << skipped << " skipped; summary " << summary_path << "\n";
  return kExitOk;
}

CommandRunner SetupRefine(CLI::App& app) {
  auto a = std::make_shared<RefineArgs>();
  app.add_option("--monst3r", a->monst3r,
                 "MonST3R output folder (pts3d_{i}.npy used if present)")
      ->required();
  app.add_option("--out", a->out,
                 "Refined trajectory (.txt MonST3R order, .tum TUM order)")
      ->required();
  app.add_option("--format", a->format, "auto (by suffix), monst3r or tum")
      ->check(CLI::IsMember({"auto", "monst3r", "tum"}))
      ->capture_default_str();
  app.add_option("--summary", a->summary,
                 "JSON summary path (default OUT.json)");
  app.add_option("--frames", a->frames, "Frames: all, 0..24, 0,3,5")
      ->capture_default_str();
  app.add_flag("--joint", a->joint, "Refine all frames in one problem");
  app.add_flag("--refine-focal", a->options.refine_focal,
               "Refine the focal (shared when --joint)");
  app.add_flag("--all-pixels", a->all_pixels,
               "Use dynamic pixels too (default: static only)");
  app.add_option("--mask", a->mask, "Dynamic mask: plain or enlarged")
      ->check(CLI::IsMember({"plain", "enlarged"}))
      ->capture_default_str();
  app.add_option("--min-confidence", a->filter.min_confidence,
                 "Confidence threshold in [0,1]")
      ->capture_default_str();
  app.add_option("--min-depth", a->filter.min_depth,
                 "Minimum depth (MonST3R units)")
      ->capture_default_str();
  app.add_option("--max-depth", a->filter.max_depth,
                 "Maximum depth (MonST3R units)")
      ->capture_default_str();
  app.add_option("--loss", a->loss, "Robust loss: none, huber, cauchy")
      ->check(CLI::IsMember({"none", "huber", "cauchy"}))
      ->capture_default_str();
  app.add_option("--loss-scale", a->options.loss_scale_px,
                 "Robust loss scale (px)")
      ->capture_default_str();
  app.add_option("--samples", a->options.num_samples,
                 "Sampled pixels per frame (0 = all)")
      ->capture_default_str();
  app.add_option("--seed", a->options.seed, "Sampling seed")
      ->capture_default_str();
  app.add_option("--smooth-translation",
                 a->options.smoothness_translation_weight,
                 "Joint: weight of the camera-centre second difference")
      ->capture_default_str();
  app.add_option("--smooth-rotation", a->options.smoothness_rotation_weight,
                 "Joint: weight of the relative-rotation change (per radian)")
      ->capture_default_str();
  app.add_option("--threads", a->options.num_threads,
                 "Threads (1..256; one frame pair per thread)")
      ->check(ThreadCountValidator() & CLI::PositiveNumber)
      ->capture_default_str();
  return [a] { return RunRefine(*a); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    refine_poses,
    "refine-poses",
    "Refine camera poses by reprojection least squares (eq. 3)",
    SetupRefine);

}  // namespace geodrive
