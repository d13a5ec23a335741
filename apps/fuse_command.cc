// `geodrive fuse --monst3r DIR --out cloud.ply`: MonST3R folder -> filtered,
// fused world cloud.

#include <iostream>
#include <memory>

#include "apps/cli/cli.h"
#include "geometry/fusion.h"
#include "geometry/monst3r.h"
#include "geometry/point_cloud_io.h"
#include "geometry/pointmap.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

struct FuseArgs {
  std::string monst3r, out, frames = "all", mask = "enlarged";
  bool static_only = false, dynamic_only = false, init_conf = false;
  double depth_scale = 1.0;
  PointmapFilterOptions filter;
  FusionOptions fusion;
  bool no_sor = false;
  bool ascii = false;
};

int RunFuse(FuseArgs a) {
  GEODRIVE_CHECK_INPUT(!(a.static_only && a.dynamic_only),
                       "--static-only and --dynamic-only exclude each other");
  a.filter.selection = a.static_only    ? PixelSelection::kStaticOnly
                       : a.dynamic_only ? PixelSelection::kDynamicOnly
                                        : PixelSelection::kAll;
  a.filter.mask_kind =
      a.mask == "plain" ? DynamicMaskKind::kPlain : DynamicMaskKind::kEnlarged;
  a.fusion.statistical_outlier_removal = !a.no_sor;
  CheckOutputFileOutsideInput(a.out, a.monst3r);
  a.filter.Check();
  a.fusion.Check();
  const Monst3rFolder folder = Monst3rFolder::Open(a.monst3r);
  const std::vector<int> frames = ParseFrameList(a.frames, folder.num_frames());
  Monst3rLoadOptions lo;
  lo.init_confidence = a.init_conf;
  lo.confidence = !a.init_conf;
  std::vector<Pointmap> pms;
  for (const auto& f : folder.LoadFrames(frames, lo)) {
    pms.push_back(BuildPointmap(
        f, a.depth_scale,
        a.init_conf ? ConfidenceSource::kInitConf : ConfidenceSource::kConf));
  }
  const FusedCloud fused = FusePointmaps(pms, a.filter, a.fusion);
  if (EndsWith(a.out, ".ply")) {
    WritePly(a.out, fused.cloud, !a.ascii);
  } else {
    WritePointCloud(a.out, fused.cloud);
  }
  const char* units =
      a.depth_scale == 1.0 ? "MonST3R units" : "metres (depth scale applied)";
  std::cout << a.out << ": " << fused.cloud.size()
            << " points, world frame of pred_traj.txt, " << units << "\n"
            << "  " << fused.summary.ToString() << "\n";
  return kExitOk;
}

CommandRunner SetupFuse(CLI::App& app) {
  auto a = std::make_shared<FuseArgs>();
  app.add_option("--monst3r", a->monst3r,
                 "MonST3R output folder (pred_traj.txt, frame_*.npy, ...)")
      ->required();
  app.add_option("--out", a->out,
                 "Output cloud (.ply binary; .pcd also accepted)")
      ->required();
  app.add_option("--frames", a->frames,
                 "Frames to fuse: all, 0..24, 0,3,5 or 0..24:2")
      ->capture_default_str();
  app.add_flag("--static-only", a->static_only,
               "Keep static pixels only (dynamic masks)");
  app.add_flag("--dynamic-only", a->dynamic_only, "Keep dynamic pixels only");
  app.add_option("--mask", a->mask,
                 "Dynamic mask deciding static/dynamic: plain or enlarged")
      ->check(CLI::IsMember({"plain", "enlarged"}))
      ->capture_default_str();
  app.add_option("--min-confidence", a->filter.min_confidence,
                 "Confidence threshold in [0,1] on 1 - 1/raw (paper tau = "
                 "0.65; 0 = off)")
      ->capture_default_str();
  app.add_flag("--init-conf", a->init_conf,
               "Use init_conf_{i}.npy instead of conf_{i}.npy");
  app.add_option(
         "--min-depth", a->filter.min_depth,
         "Minimum z-depth (MonST3R units, or metres with --depth-scale)")
      ->capture_default_str();
  app.add_option("--max-depth", a->filter.max_depth,
                 "Maximum z-depth (same units)")
      ->capture_default_str();
  app.add_option("--depth-scale", a->depth_scale,
                 "Metres per MonST3R unit, once known (scales depth and poses)")
      ->capture_default_str();
  app.add_option("--stride", a->filter.stride,
                 "Use every n-th pixel in u and v")
      ->capture_default_str();
  app.add_option(
         "--voxel-size", a->fusion.voxel_size,
         "Voxel size (cloud units); 0 = auto (2% of median depth), < 0 = off")
      ->capture_default_str();
  app.add_flag("--no-sor", a->no_sor, "Disable statistical outlier removal");
  app.add_option("--sor-k", a->fusion.sor_mean_k,
                 "Statistical outlier removal: neighbours")
      ->capture_default_str();
  app.add_option("--sor-std", a->fusion.sor_stddev_mul,
                 "Statistical outlier removal: std-dev multiplier")
      ->capture_default_str();
  app.add_flag("--radius-outlier", a->fusion.radius_outlier_removal,
               "Enable radius outlier removal");
  app.add_option("--ror-radius", a->fusion.ror_radius,
                 "Radius outlier removal radius (cloud units; 0 = 3 voxels)")
      ->capture_default_str();
  app.add_option("--ror-min-neighbors", a->fusion.ror_min_neighbors,
                 "Radius outlier removal: minimum neighbours")
      ->capture_default_str();
  app.add_flag("--ascii", a->ascii, "Write ASCII PLY");
  return [a] { return RunFuse(*a); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    fuse,
    "fuse",
    "Fuse a MonST3R folder's filtered pointmaps into one coloured cloud",
    SetupFuse);

}  // namespace geodrive
