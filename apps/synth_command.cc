// `geodrive synth`: writes the synthetic nuScenes-like world as a nuScenes
// dataset or as Waymo v1 segments (docs/SYNTHETIC.md).

#include <iostream>
#include <map>
#include <memory>
#include <sstream>

#include "apps/cli/cli.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "dataset/synthetic/synthetic_waymo.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// What `geodrive synth` writes.
enum class SynthFormat {
  kNuScenes,  // a nuScenes dataroot (tables, sensor files, MonST3R folders)
  kWaymo,     // Waymo v1 segments, one TFRecord per scene
};

struct SynthArgs {
  std::string out;
  SynthFormat format = SynthFormat::kNuScenes;
  SyntheticDatasetOptions options;
  // Empty: 900x1600 for nuScenes, 1280x1920 for Waymo.
  std::string size;
  std::string cameras = "CAM_FRONT";
  int lidar_columns = 2650;
};

std::vector<std::string> SplitCommas(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

// --format waymo: the scenes as Waymo v1 segments.
int RunSynthWaymo(const SynthArgs& a) {
  const SyntheticDatasetOptions& n = a.options;
  SyntheticWaymoOptions o;
  o.num_scenes = n.num_scenes;
  o.seed = n.seed;
  ParseSizeHxW(a.size.empty() ? "1280x1920" : a.size, "--size", &o.image_height,
               &o.image_width);
  o.scene_duration_s = n.scene_duration_s;
  o.reverse_after_stop = n.reverse_after_stop;
  o.lidar_columns = a.lidar_columns;
  o.jpeg_quality = n.jpeg_quality;
  const std::string err = o.Validate();
  GEODRIVE_CHECK_INPUT(err.empty(), "geodrive synth: ", err);
  o.progress = [](const std::string& line) {
    std::cout << "  " << line << std::endl;
  };
  std::cout << "geodrive synth: " << o.num_scenes << " Waymo segment(s), seed "
            << o.seed << ", " << o.image_width << "x" << o.image_height << ", "
            << o.scene_duration_s << " s per segment -> " << a.out << std::endl;
  const SyntheticWaymoSummary s = WriteSyntheticWaymo(o, a.out);
  std::cout << s.BriefReport() << std::endl;
  return kExitOk;
}

int RunSynth(SynthArgs& a) {
  if (a.format == SynthFormat::kWaymo) return RunSynthWaymo(a);
  SyntheticDatasetOptions& o = a.options;
  ParseSizeHxW(a.size.empty() ? "900x1600" : a.size, "--size", &o.image_height,
               &o.image_width);
  if (a.cameras == "all") {
    o.cameras = {"CAM_FRONT", "CAM_FRONT_RIGHT", "CAM_BACK_RIGHT",
                 "CAM_BACK",  "CAM_BACK_LEFT",   "CAM_FRONT_LEFT"};
  } else {
    o.cameras = SplitCommas(a.cameras);
  }
  const std::string err = o.Validate();
  GEODRIVE_CHECK_INPUT(err.empty(), "geodrive synth: ", err);
  o.progress = [](const std::string& line) {
    std::cout << "  " << line << std::endl;
  };
  std::cout << "geodrive synth: " << o.num_scenes << " scene(s), seed "
            << o.seed << ", " << o.image_width << "x" << o.image_height << ", "
            << o.scene_duration_s << " s per scene"
            << (o.tables_only ? ", tables only" : "")
            << (o.write_monst3r ? ", with MonST3R clips" : "") << " -> "
            << a.out << std::endl;
  const SyntheticDatasetSummary s = WriteSyntheticDataset(o, a.out);
  std::cout << s.BriefReport() << std::endl;
  std::cout << "nuScenes dataroot: " << a.out << " (version " << o.version
            << ")";
  if (!s.monst3r_clip_ids.empty()) {
    std::cout << "; MonST3R folders: " << a.out
              << "/monst3r/<clip_id>, ground truth: " << a.out
              << "/monst3r_gt/<clip_id>.json";
  }
  std::cout << std::endl;
  return kExitOk;
}

CommandRunner SetupSynth(CLI::App& app) {
  auto a = std::make_shared<SynthArgs>();
  SyntheticDatasetOptions& o = a->options;
  app.footer(
      "Writes a procedural street world as a real nuScenes dataset (13 JSON "
      "tables in "
      "OUT/VERSION/, CAM_* JPEGs and LIDAR_TOP .pcd.bin under samples/ and "
      "sweeps/, map masks) "
      "with exact ground truth. --monst3r adds MonST3R demo-format folders "
      "OUT/monst3r/<clip_id>/ "
      "for 25-frame CAM_FRONT clips (every --monst3r-stride frames from 0) "
      "with a ground-truth "
      "sidecar OUT/monst3r_gt/<clip_id>.json. Same seed -> byte-identical "
      "files. Layout: "
      "docs/SYNTHETIC.md.\n\nExamples:\n  geodrive synth --out /tmp/s --scenes "
      "2 --seed 7\n"
      "  geodrive synth --out /tmp/s --scenes 1 --size 450x800 --monst3r "
      "--duration 8\n"
      "  geodrive synth --out /tmp/trainval --scenes 850 --tables-only "
      "--cameras all --radars "
      "--version v1.0-trainval\n"
      "  geodrive synth --format waymo --out /tmp/w --scenes 2 --size "
      "320x480 --duration 5\n\n"
      "--format waymo writes each scene as a Waymo Open Dataset v1 segment, "
      "OUT/segment-<context>_with_camera_labels.tfrecord: 10 Hz frames with "
      "the pose, five cameras (FRONT, FRONT_LEFT, FRONT_RIGHT, SIDE_LEFT, "
      "SIDE_RIGHT; --size is FRONT's, SIDE_* keep 886/1280 of its height), "
      "laser_labels, projected_lidar_labels, camera_labels and TOP's range "
      "image (64 rows x --lidar-columns). The nuScenes-only options are "
      "ignored.");
  app.add_option("--out", a->out,
                 "Output folder (the nuScenes dataroot, or the folder of the "
                 "Waymo segments)")
      ->required();
  app.add_option("--format", a->format,
                 "nuscenes (a nuScenes dataroot; default) or waymo (Waymo v1 "
                 "TFRecord segments)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, SynthFormat>{
              {"nuscenes", SynthFormat::kNuScenes},
              {"waymo", SynthFormat::kWaymo}},
          CLI::ignore_case))
      ->option_text("TEXT:{nuscenes,waymo}=nuscenes");
  app.add_option("--scenes", o.num_scenes, "Number of scenes (one log each)")
      ->capture_default_str();
  app.add_option("--seed", o.seed, "World seed")->capture_default_str();
  app.add_option("--size", a->size,
                 "Camera image size HxW, height first as every --size "
                 "(intrinsics scale with it); default 900x1600, with "
                 "--format waymo 1280x1920 (FRONT)");
  app.add_option("--cameras", a->cameras,
                 "Comma-separated CAM_* channels, or 'all' for the six "
                 "nuScenes cameras")
      ->capture_default_str();
  app.add_flag("--monst3r", o.write_monst3r,
               "Write MonST3R folders + ground-truth sidecars");
  app.add_flag("--tables-only", o.tables_only,
               "Metadata only (no images, sweeps or MonST3R); any scale");
  app.add_flag("--radars", o.radars,
               "With --tables-only: add the five RADAR_* channels (13 Hz)");
  app.add_option("--version", o.version, "Table folder name")
      ->capture_default_str();
  app.add_option("--duration", o.scene_duration_s,
                 "Seconds per scene (2 keyframes per second)")
      ->capture_default_str();
  app.add_option("--lidar-azimuth-steps", o.lidar_azimuth_steps,
                 "LIDAR_TOP rays per ring per sweep (32 rings)")
      ->capture_default_str();
  app.add_option("--monst3r-stride", o.monst3r_clip_stride,
                 "CAM_FRONT frames between MonST3R clip starts (multiple of 6)")
      ->capture_default_str();
  app.add_option("--monst3r-max-clips", o.monst3r_max_clips_per_scene,
                 "At most this many MonST3R clips per scene (0 = all)")
      ->capture_default_str();
  app.add_option("--depth-noise", o.monst3r_depth_noise,
                 "MonST3R multiplicative depth noise sigma (fraction)")
      ->capture_default_str();
  app.add_option("--pose-noise-deg", o.monst3r_pose_noise_deg,
                 "MonST3R rotation noise (deg)")
      ->capture_default_str();
  app.add_option("--pose-noise-m", o.monst3r_pose_noise_m,
                 "MonST3R translation noise (m)")
      ->capture_default_str();
  app.add_option(
         "--outliers", o.monst3r_outlier_fraction,
         "Fraction of MonST3R pixels with wrong depth and -inf confidence")
      ->capture_default_str();
  app.add_option("--lidar-columns", a->lidar_columns,
                 "--format waymo: columns of TOP's range image (64 rows)")
      ->capture_default_str();
  app.add_flag("!--no-reverse", o.reverse_after_stop,
               "Brake-and-stop scenes do not reverse after the stop");
  return [a] { return RunSynth(*a); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    synth,
    "synth",
    "Write a synthetic world with exact ground truth as a nuScenes dataset "
    "(and MonST3R-format outputs) or as Waymo v1 segments",
    SetupSynth);

}  // namespace geodrive
