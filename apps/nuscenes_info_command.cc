// `geodrive nuscenes-info --dataroot DIR --version V`: what a nuScenes(-format)
// dataset holds.

#include <iomanip>
#include <iostream>
#include <map>
#include <memory>

#include "apps/command.h"
#include "dataset/clips.h"
#include "dataset/nuscenes.h"

namespace geodrive {
namespace {

struct NuscenesInfoArgs {
  std::string dataroot;
  std::string version = "v1.0-mini";
  int stride = ClipOptions().stride;
  int rate = 0;
  bool keyframe_start = false;
};

int RunNuscenesInfo(const NuscenesInfoArgs& args) {
  NuscenesOptions options;
  options.dataroot = args.dataroot;
  options.version = args.version;
  const Nuscenes nusc(options);
  std::cout << nusc.VersionDir() << ": " << nusc.summary().Brief() << "\n";
  std::cout << "scenes " << nusc.scenes().size() << ", samples "
            << nusc.samples().size() << ", sample_data "
            << nusc.sample_data().size() << ", ego_poses "
            << nusc.ego_poses().size() << ", logs " << nusc.logs().size()
            << ", maps " << nusc.maps().size() << "\n";
  // Samples (keyframes) and sweeps per channel.
  std::vector<size_t> keys(nusc.sensors().size()),
      sweeps(nusc.sensors().size());
  for (const auto& sd : nusc.sample_data())
    (sd.is_key_frame ? keys : sweeps)[sd.sensor]++;
  std::cout << "channel              modality  samples   sweeps\n";
  for (size_t s = 0; s < nusc.sensors().size(); ++s) {
    std::cout << std::left << std::setw(20) << nusc.sensors()[s].channel << " "
              << std::setw(9) << ToString(nusc.sensors()[s].modality)
              << std::right << std::setw(8) << keys[s] << " " << std::setw(8)
              << sweeps[s] << "\n";
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
            << "): " << summary.clips << " (" << summary.Brief() << ")\n";
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
