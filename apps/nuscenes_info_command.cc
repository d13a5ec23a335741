// `geodrive nuscenes-info --dataroot DIR --version V`: what a nuScenes(-format)
// dataset holds.

#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>

#include "apps/cli/cli.h"
#include "dataset/nuscenes_clips.h"
#include "dataset/nuscenes.h"

namespace geodrive {
namespace {

struct NuscenesInfoArgs {
  std::string dataroot;
  std::string version = "v1.0-mini";
  int stride = ClipOptions().stride;
  int rate = 0;
  bool keyframe_start = false;
  int clip_frames = ClipOptions().num_frames;
  std::string frames = "all";
};

int RunNuscenesInfo(const NuscenesInfoArgs& args) {
  NuscenesOptions options;
  options.dataroot = args.dataroot;
  options.version = args.version;
  const Nuscenes nusc(options);
  std::cout << nusc.VersionDir() << ": " << nusc.summary().BriefReport()
            << "\n";
  std::cout << "scenes " << nusc.scenes().size() << ", samples "
            << nusc.samples().size() << ", sample_data "
            << nusc.sample_data().size() << ", ego_poses "
            << nusc.ego_poses().size() << ", logs " << nusc.logs().size()
            << ", maps " << nusc.maps().size() << "\n";
  // Samples (keyframes) and sweeps per channel, and how many of the listed
  // files are on disk (real extracts often ship keyframe files only).
  const size_t n_sensors = nusc.sensors().size();
  std::vector<size_t> keys(n_sensors), sweeps(n_sensors), keys_on_disk(n_sensors),
      sweeps_on_disk(n_sensors);
  for (size_t i = 0; i < nusc.sample_data().size(); ++i) {
    const auto& sd = nusc.sample_data()[i];
    (sd.is_key_frame ? keys : sweeps)[sd.sensor]++;
    std::error_code ec;
    if (std::filesystem::is_regular_file(
            nusc.DataPath(static_cast<int32_t>(i)), ec))
      (sd.is_key_frame ? keys_on_disk : sweeps_on_disk)[sd.sensor]++;
  }
  std::cout << "channel              modality  samples (on disk)   sweeps (on "
               "disk)\n";
  for (size_t s = 0; s < n_sensors; ++s) {
    std::cout << std::left << std::setw(20) << nusc.sensors()[s].channel << " "
              << std::setw(9) << ToString(nusc.sensors()[s].modality)
              << std::right << std::setw(8) << keys[s] << " (" << std::setw(7)
              << keys_on_disk[s] << ") " << std::setw(8) << sweeps[s] << " ("
              << std::setw(7) << sweeps_on_disk[s] << ")\n";
  }
  std::map<std::string, size_t> per_category;
  for (size_t a = 0; a < nusc.sample_annotations().size(); ++a) {
    per_category[nusc.CategoryName(static_cast<int32_t>(a))]++;
  }
  std::cout << "annotations " << nusc.sample_annotations().size()
            << " (instances " << nusc.instances().size() << ")\n";
  for (const auto& [name, n] : per_category) {
    std::cout << "  " << std::left << std::setw(40) << name << std::right
              << std::setw(8) << n << "\n";
  }
  ClipOptions clip_options;
  clip_options.stride = args.stride;
  clip_options.target_rate_hz = args.rate;
  clip_options.start_at_keyframe = args.keyframe_start;
  clip_options.num_frames = args.clip_frames;
  clip_options.keyframes_only = args.frames == "keyframes";
  if (nusc.FindSensor(clip_options.channel) == kNoIndex) {
    std::cout << "clips: no " << clip_options.channel << " channel\n";
    return kExitOk;
  }
  ClipSelectionSummary summary;
  SelectClips(nusc, clip_options, &summary);
  std::cout << clip_options.num_frames << "-frame " << clip_options.channel
            << " clips (stride " << clip_options.stride
            << (args.rate > 0
                    ? ", resampled to " + std::to_string(args.rate) + " Hz"
                    : "")
            << (args.keyframe_start ? ", keyframe starts" : "")
            << (clip_options.keyframes_only ? ", keyframes only" : "")
            << "): " << summary.clips << " (" << summary.BriefReport() << ")\n";
  return kExitOk;
}

CommandRunner SetupNuscenesInfo(CLI::App& app) {
  auto args = std::make_shared<NuscenesInfoArgs>();
  app.add_option("--dataroot", args->dataroot,
                 "nuScenes root (holds <version>/, samples/, sweeps/)")
      ->required();
  app.add_option("--version", args->version,
                 "Table folder, e.g. v1.0-mini or v1.0-trainval")
      ->capture_default_str();
  app.add_option("--stride", args->stride, "Frames between clip starts")
      ->capture_default_str();
  app.add_option("--rate", args->rate,
                 "Resample clips to this rate in Hz (0 = no resampling)")
      ->capture_default_str();
  app.add_flag("--keyframe-start", args->keyframe_start,
               "Start clips only at keyframes");
  app.add_option("--clip-frames", args->clip_frames, "Frames per clip")
      ->capture_default_str();
  app.add_option("--frames", args->frames,
                 "Clip frames: all (keyframes and sweeps) or keyframes")
      ->check(CLI::IsMember({"all", "keyframes"}))
      ->capture_default_str();
  return [args] { return RunNuscenesInfo(*args); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    nuscenes_info,
    "nuscenes-info",
    "Print the scenes, sample/sweep counts per channel, annotations and "
    "25-frame clips of a nuScenes dataset",
    SetupNuscenesInfo);

}  // namespace geodrive
