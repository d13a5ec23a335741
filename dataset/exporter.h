#pragma once
// Exports of the pairs for other trainers: one abstract Exporter, one file per
// format (dataset/export_<format>.cc), created by CreateExporter(format).
//
// An exporter states what its trainer's loader needs (ExportRequirements:
// frames, size, depth), so that build-dataset renders the condition at the
// trainer's size and refuses a clip it cannot serve with one error naming the
// requirement. Per clip it writes its files into the pair folder being built
// (committed atomically with it, so resume and shards need nothing more);
// Finish() then writes the format's index under OUT/ (links, sample lists,
// train/val splits) from the committed pair folders.
//
// The trainers' loaders, cited at file and line: docs/reference/
// trainer-formats.md.

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/rigid3.h"

namespace geodrive {

struct BoxSequences;
struct PairMeta;

// The formats written beside our pairs.
enum class ExportFormat {
  // GeoDrive's released trainer (train.py): OUT/geodrive_upstream/.
  kGeodriveUpstream,
  // StreetCrafter's video-diffusion trainer (video_diffusion/train.py):
  // OUT/streetcrafter/meta_info_{train,val}.json.
  kStreetCrafter,
  // GEN3C's inference input (gen3c_dynamic.py): one folder per clip,
  // OUT/gen3c/<clip>/{rgb.mp4, depth.npz, mask.npz, camera.npz}.
  kGen3c,
};
// Every format, in enum order.
std::vector<ExportFormat> AllExportFormats();
// "geodrive-upstream", "streetcrafter", "gen3c".
std::string ToString(ExportFormat format);
// Parses one format name; throws InputError listing the names otherwise.
ExportFormat ParseExportFormat(const std::string& text);
// Parses "FORMAT[,FORMAT...]" ("none" or "" = no export); the result is
// sorted and without repeats. Throws InputError naming a bad element.
std::vector<ExportFormat> ParseExportFormats(const std::string& text);
// The formats joined by ',' in the order given ("" when empty).
std::string ToString(const std::vector<ExportFormat>& formats);

// What a trainer's loader needs of a clip.
struct ExportRequirements {
  // Frames a clip must have at least (0 = any).
  int min_frames = 0;
  // Frames a clip must have exactly (0 = any count from min_frames on).
  int exact_frames = 0;
  // Frame counts beyond min_frames come in steps of this many (0 = any
  // count): min_frames + frame_step N (GEN3C: 121, 241, ...).
  int frame_step = 0;
  // Size the frames and the condition are written at; 0 = the pair's size
  // (--size). A size other than the pair's renders the condition a second
  // time at that size (never a resize of ours).
  int width = 0, height = 0;
  // Frame rate the trainer assumes (Hz; 0 = any). Informative: clips are not
  // resampled.
  double fps = 0;
  // Per-frame condition z-depth and drawn mask (ExportClip::depth, ::drawn).
  bool depth = false;
  // The renderer's frames before the resize to the pair's size
  // (ExportClip::native_condition; only with width = height = 0).
  bool native_condition = false;
};

// Options shared by the exporters.
struct ExportOptions {
  // Fraction of the scenes listed for validation where the format has
  // train/val lists, in [0, 1]; rounded to a whole number of scenes, at
  // least one scene left for training when below 1.
  double val_fraction = 0.1;
  // Seed of the by-scene split (the same seed and scenes give the same
  // split whatever the clip order).
  uint64_t split_seed = 0;
  // True when every field is in range.
  bool Check() const;
};

// What the builder has of one clip, at the exporter's size. The pointers are
// non-null unless noted and outlive WriteClip.
struct ExportClip {
  std::string clip_id;
  // The scene the clip comes from (the key of by-scene splits).
  std::string scene_name;
  // Index of the clip in the dataset's clip list (-1 = unknown).
  int clip_index = -1;
  // Camera frames (RGB CV_8UC3) at the exporter's size.
  const std::vector<cv::Mat>* images = nullptr;
  // Condition frames (RGB CV_8UC3, black where nothing was drawn), same size.
  const std::vector<cv::Mat>* condition = nullptr;
  // With ExportRequirements::depth: the condition's z-depth per frame
  // (CV_32F, the scene's units, 0 = no point) and drawn mask (CV_8U, 255 = a
  // point was drawn); null otherwise.
  const std::vector<cv::Mat>* depth = nullptr;
  const std::vector<cv::Mat>* drawn = nullptr;
  // With ExportRequirements::native_condition: the renderer's frames before
  // the resize to the pair's size; null otherwise.
  const std::vector<cv::Mat>* native_condition = nullptr;
  // Frame 0 at the source size (empty: read it from first_frame_path).
  cv::Mat first_frame_full;
  std::string first_frame_path;
  // Intrinsics at the exporter's size (integer-index pixel centres).
  PinholeCamera camera;
  // Pose of every frame in the scene frame (camera 0 at frame 0), OpenCV
  // axes.
  std::vector<Rigid3d> world_from_cam;
  // True when depth and poses are in metres.
  bool metric = true;
  // Vehicle boxes at the pair's size (null when none were collected).
  const BoxSequences* boxes = nullptr;
};

class Exporter {
 public:
  virtual ~Exporter() = default;
  virtual ExportFormat Format() const = 0;
  virtual ExportRequirements Requirements() const = 0;
  // Writes the clip's files under `pair_dir` (the pair folder being built)
  // and records them in meta->files. Throws InputError naming the file.
  virtual void WriteClip(const ExportClip& clip,
                         const std::string& pair_dir,
                         PairMeta* meta) const = 0;
  // After the clips: (re)writes the format's index under `out` (the
  // build-dataset output) from the pair folders that hold this format's
  // files. Returns the number of samples listed; a no-op (0) when no pair has
  // them.
  virtual int Finish(const std::string& out) const = 0;
};

// The exporter of `format`.
std::unique_ptr<Exporter> CreateExporter(ExportFormat format,
                                         const ExportOptions& options = {});

// True when a clip of `num_frames` frames meets `req`'s frame counts.
bool AcceptsFrameCount(const ExportRequirements& req, int num_frames);
// The frame counts `req` accepts, in words: "25 frames", "121, 241, ...
// frames (120 N + 1)".
std::string FrameCountText(const ExportRequirements& req);

// Throws InputError "<clip_id>: <format> needs N frames; this clip has M"
// when a clip of `num_frames` frames breaks `exporter`'s requirements.
void CheckClipForExport(const Exporter& exporter,
                        const std::string& clip_id,
                        int num_frames);

}  // namespace geodrive
