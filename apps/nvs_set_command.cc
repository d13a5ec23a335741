// `geodrive nvs-set`: the novel-view-synthesis evaluation set of the GeoDrive
// paper from a list of segments: per segment the reference camera's clip from
// its first frame, one pair per lateral offset whose condition is rendered
// along the trajectory shifted sideways (build-dataset's novel-view pairs,
// BuildDatasetOptions::lateral_offsets_m) and whose ground truth is the real
// frames; OUT/manifest.jsonl for `geodrive-diffusion generate --manifest` and
// OUT/pairs/ for `geodrive eval --metrics fid,fvd`.

#include <cmath>
#include <cstdlib>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "apps/cli/cli.h"
#include "dataset/build_dataset.h"
#include "dataset/drive_dataset.h"
#include "geometry/util/progress.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// Clip starts this far apart leave one clip per segment: the one from its
// first frame (segments are at most a few thousand frames).
constexpr int kOneClipPerSegment = 1 << 30;

struct NvsArgs {
  BuildDatasetOptions options;
  std::string dataset = "auto";
  std::string segments = "all";
  std::string offsets = "-3,3";
  std::string size = "480x720";
};

// "a,b,c" -> {"a", "b", "c"}, items trimmed of spaces; empty items dropped.
std::vector<std::string> SplitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    const size_t b = item.find_first_not_of(" \t");
    const size_t e = item.find_last_not_of(" \t");
    if (b != std::string::npos) out.push_back(item.substr(b, e - b + 1));
  }
  return out;
}

// "--offsets -3,3" -> {-3, 3}: metres, left positive; each item a finite
// number, at least one.
std::vector<double> ParseOffsets(const std::string& text) {
  std::vector<double> out;
  for (const std::string& item : SplitList(text)) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    GEODRIVE_CHECK_INPUT(*end == '\0' && std::isfinite(v), "--offsets: '", item,
                         "' is not a number of metres (a comma list, left "
                         "positive, e.g. --offsets -3,3)");
    out.push_back(v);
  }
  GEODRIVE_CHECK_INPUT(!out.empty(), "--offsets: no offset in '", text,
                       "' (a comma list of metres, e.g. --offsets -3,3)");
  return out;
}

// Segment name (DriveClip::scene_name: Waymo context name, nuScenes scene
// name) -> the id of its clip from the first frame, in dataset order.
std::vector<std::pair<std::string, std::string>> FirstClipOfEachSegment(
    const DriveDataset& dataset) {
  std::vector<std::pair<std::string, std::string>> out;
  std::set<std::string> seen;
  for (const std::string& id : dataset.ClipIds()) {
    const std::string scene = dataset.LoadClip(id).scene_name;
    if (seen.insert(scene).second) out.emplace_back(scene, id);
  }
  return out;
}

// The clip ids of the segments `--segments` names ("all": every segment).
// An unknown name is an InputError listing the dataset's segments.
std::vector<std::string> SelectSegments(const NvsArgs& a,
                                        const DriveDataset& dataset) {
  const auto segments = FirstClipOfEachSegment(dataset);
  GEODRIVE_CHECK_INPUT(!segments.empty(), a.options.dataroot,
                       ": no segment has ", a.options.clip_frames,
                       " frames of the front camera (--frames)");
  std::vector<std::string> clips;
  if (a.segments == "all") {
    for (const auto& [name, clip] : segments) clips.push_back(clip);
    return clips;
  }
  std::map<std::string, std::string> by_name(segments.begin(), segments.end());
  const std::vector<std::string> names = SplitList(a.segments);
  GEODRIVE_CHECK_INPUT(!names.empty(), "--segments: no segment named in '",
                       a.segments, "'");
  std::set<std::string> named;
  for (const std::string& name : names) {
    const auto it = by_name.find(name);
    if (it == by_name.end()) {
      std::string known;
      for (size_t k = 0; k < segments.size() && k < 8; ++k)
        known += (k ? ", " : "") + segments[k].first;
      if (segments.size() > 8) known += ", ...";
      ThrowInputError("--segments", "'", name, "' is not a segment of ",
                      a.options.dataroot, " with ", a.options.clip_frames,
                      " front-camera frames (", segments.size(),
                      " segments: ", known, ")");
    }
    GEODRIVE_CHECK_INPUT(named.insert(name).second, "--segments: '", name,
                         "' is named twice");
    clips.push_back(it->second);
  }
  return clips;
}

int RunNvsSet(NvsArgs& a) {
  BuildDatasetOptions& o = a.options;
  GEODRIVE_CHECK_INPUT(!o.dataroot.empty() && !o.out.empty(),
                       "nvs-set: --dataroot and --out are required");
  o.dataset = ResolveDatasetFormat(a.dataset, o.dataroot);
  o.lateral_offsets_m = ParseOffsets(a.offsets);
  ParseSizeHxW(a.size, "--size", &o.height, &o.width);
  o.clip_stride = kOneClipPerSegment;
  o.Check();
  {
    DriveDatasetOptions dso;  // build-dataset's clips (single camera)
    dso.format = o.dataset;
    dso.root = o.dataroot;
    dso.version = o.version;
    dso.clip_frames = o.clip_frames;
    dso.clip_stride = o.clip_stride;
    dso.frames = o.frames;
    const std::unique_ptr<DriveDataset> dataset = OpenDriveDataset(dso);
    o.clips = SelectSegments(a, *dataset);
  }
  InstallStopSignalHandlers();
  const BuildDatasetSummary s = BuildDataset(o);
  std::cout << "nvs-set: " << o.clips.size() << " segment(s) x "
            << o.lateral_offsets_m.size() << " offset(s): " << s.BriefReport()
            << "\n"
            << "pairs: " << o.out << "/pairs/  manifest: " << o.out
            << "/manifest.jsonl  report: " << o.out << "/report.html\n"
            << "generate: geodrive-diffusion generate --manifest " << o.out
            << "/manifest.jsonl --out-dir PRED --config cogvideox-5b-i2v "
               "--weights BACKBONE --branch-weights ENCODER --vae-weights "
               "VAE\n"
            << "evaluate: geodrive eval --pred PRED --gt " << o.out
            << "/pairs --metrics fid,fvd --fid-model pt_inception.pt "
               "--fvd-model i3d_torchscript.pt --out PRED_eval/report.json\n";
  if (s.interrupted) return kExitInterrupted;
  if (s.failed + s.log_write_errors > 0) {
    std::cerr << "nvs-set: completed with failures (see " << o.out
              << "/failures.jsonl)\n";
    return kExitCompletedWithFailures;
  }
  return kExitOk;
}

CommandRunner SetupNvsSet(CLI::App& app) {
  auto a = std::make_shared<NvsArgs>();
  BuildDatasetOptions& o = a->options;
  app.footer(
      "The novel-view protocol of the GeoDrive paper (five Waymo validation "
      "segments, front\n"
      "camera, the trajectory shifted 3 m left and right, FID and FVD against "
      "the real frames).\n"
      "Per segment the front camera's clip from its first frame (--frames "
      "frames) is read; per\n"
      "offset d one pair OUT/pairs/<clip>_shift_<left|right>_<d>m/ is "
      "written: first_frame.png\n"
      "and gt.mp4 are the real frames, cond.mp4 the condition rendered along "
      "the clip's camera\n"
      "trajectory with every frame's ego pose moved d metres along its own y "
      "axis (ego frame x\n"
      "forward, y left: positive = left), the camera with it; meta.json "
      "novel_view says the\n"
      "source clip and offset. OUT/manifest.jsonl lists every pair. Then:\n"
      "  geodrive-diffusion generate --manifest OUT/manifest.jsonl --out-dir "
      "PRED --weights ...\n"
      "  geodrive eval --pred PRED --gt OUT/pairs --metrics fid,fvd "
      "--fid-model ... --fvd-model ...\n"
      "FID and FVD compare distributions: the generated shifted views against "
      "the real frames.\n"
      "Resumable as build-dataset: a rerun keeps the finished pairs; a "
      "segment that fails is\n"
      "recorded in OUT/failures.jsonl and the others are built (exit 3).");
  app.add_option("--dataroot", o.dataroot,
                 "A folder of Waymo *.tfrecord segments, or a nuScenes root")
      ->required();
  app.add_option("--dataset", a->dataset,
                 "Dataset format: auto (Waymo when --dataroot holds "
                 "*.tfrecord files), waymo or nuscenes")
      ->check(CLI::IsMember({"auto", "waymo", "nuscenes"}))
      ->capture_default_str();
  app.add_option("--version", o.version, "nuScenes table folder")
      ->capture_default_str();
  app.add_option("--segments", a->segments,
                 "Comma list of segments (Waymo context names, nuScenes scene "
                 "names), or all")
      ->capture_default_str();
  app.add_option("--offsets", a->offsets,
                 "Comma list of lateral offsets in metres, left positive, "
                 "e.g. -3,3 (3 m right and 3 m left)")
      ->capture_default_str();
  app.add_option("--frames", o.clip_frames,
                 "Frames per pair, from each segment's first frame")
      ->check(CLI::Range(2, 10000))
      ->capture_default_str();
  app.add_option("--frame-source", o.frames,
                 "Which reference-camera frames make the clip: all, or "
                 "keyframes (nuScenes extracts without sweep files)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, ClipFrameSource>{
              {"all", ClipFrameSource::kAll},
              {"keyframes", ClipFrameSource::kKeyframes}},
          CLI::ignore_case))
      ->default_str("all");
  app.add_option("--out", o.out, "Output folder (pairs/, manifest.jsonl)")
      ->required();
  app.add_option("--geometry", o.geometry,
                 "Scene source: lidar (the segment's static LiDAR around "
                 "frame 0) or lidar-dense (completed frame-0 depth)")
      ->check(CLI::IsMember({"lidar", "lidar-dense"}))
      ->default_str("lidar");
  o.geometry = "lidar";
  app.add_option("--edit-mode", o.edit_mode,
                 "Vehicles: 3d (moved along their boxes) or none (static "
                 "scene only)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, PairEditMode>{{"3d", PairEditMode::k3d},
                                              {"none", PairEditMode::kNone}},
          CLI::ignore_case))
      ->default_str("3d");
  app.add_option("--size", a->size, "Output HxW")->capture_default_str();
  app.add_option("--fps", o.fps, "Frame rate of the videos")
      ->capture_default_str();
  app.add_option("--threads", o.threads, "Pairs built in parallel")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  app.add_flag("--lossless-frames", o.lossless_frames,
               "Also write gt_frames/ and cond_frames/ PNG sequences");
  app.add_flag("--quiet", o.quiet, "No progress lines");
  return [a] { return RunNvsSet(*a); };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(nvs_set,
                          "nvs-set",
                          "The paper's novel-view evaluation set: per segment "
                          "the front camera's trajectory shifted sideways",
                          SetupNvsSet);

}  // namespace geodrive
