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
struct PointCloud;

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
  // Cosmos-Drive-Dreams' RDS-HQ, the input of render_from_rds_hq.py: one
  // webdataset tar per field and clip, OUT/rds_hq/<field>/<clip>.tar.
  kRdsHq,
  // drivestudio's nuScenes layout (tools/train.py): one scene folder per
  // clip, OUT/drivestudio/%03d/.
  kDrivestudio,
};
// Every format, in enum order.
std::vector<ExportFormat> AllExportFormats();
// "geodrive-upstream", "streetcrafter", "gen3c", "rds-hq",
// "drivestudio".
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
  // The condition rendered at the exporter's size (ExportClip::condition);
  // false for an exporter that writes the frames but no condition (with
  // width x height other than the pair's, nothing is then rendered for it).
  bool condition = true;
  // Per-frame condition z-depth and drawn mask (ExportClip::depth, ::drawn).
  bool depth = false;
  // The renderer's frames before the resize to the pair's size
  // (ExportClip::native_condition; only with width = height = 0).
  bool native_condition = false;
  // False when the exporter writes no frames or condition of its own (only
  // cameras, poses, LiDAR, objects): width x height then sizes
  // ExportClip::camera alone, nothing is decoded or rendered for it, and
  // ExportClip::images and ::condition are null.
  bool frames = true;
  // LiDAR sweeps at frames 0, s, 2 s, ... (ExportClip::lidar); 0 = none.
  // Needs a metric scene and a dataset with LiDAR.
  int lidar_frame_step = 0;
  // Every annotated object at every frame, all categories
  // (ExportClip::objects). Needs a metric scene.
  bool objects = false;
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

// One LiDAR sweep of a clip (ExportClip::lidar).
struct ExportSweep {
  // The clip frame the sweep serves (the sweep nearest to the frame's time;
  // a keyframe's own sweep).
  int frame = 0;
  int64_t timestamp_us = 0;
  // Points in the sensor frame, metres: x, y, z, intensity (the dataset's
  // scale; 0 when it has none), 4 floats a point, every return (the ego
  // vehicle's own included).
  std::vector<float> xyzi;
  // The sensor's pose in the export's world (ExportClip::world_from_cam's).
  Rigid3d world_from_sensor;
  size_t size() const { return xyzi.size() / 4; }
};

// One annotated object at one frame (ExportClip::objects).
struct ExportObject {
  // Stable across the clip's frames (nuScenes: the instance token).
  std::string track_id;
  // The dataset's category in nuScenes names ("vehicle.car",
  // "human.pedestrian.adult", ...; the Waymo adapter maps to them).
  std::string category;
  // Box centre pose in the export's world: x along the length (heading), y
  // left along the width, z up.
  Rigid3d world_from_box;
  // Length, width, height (metres), along the box's x, y, z.
  Eigen::Vector3d lwh = Eigen::Vector3d::Zero();
  // Speed of the box centre (m/s): central difference over the track's
  // neighbouring frames in the clip; 0 for a track seen in one frame.
  double speed_mps = 0;
};

// What the builder has of one clip, at the exporter's size. The pointers are
// non-null unless noted and outlive WriteClip.
struct ExportClip {
  std::string clip_id;
  // The camera channel ("CAM_FRONT", ...): set for a rig's cameras
  // (Exporter::WriteRig), empty for a single camera.
  std::string channel;
  // The scene the clip comes from (the key of by-scene splits).
  std::string scene_name;
  // Index of the clip in the dataset's clip list (-1 = unknown).
  int clip_index = -1;
  // Camera frames (RGB CV_8UC3) at the exporter's size (null when
  // ExportRequirements::frames is false).
  const std::vector<cv::Mat>* images = nullptr;
  // Condition frames (RGB CV_8UC3, black where nothing was drawn), same size
  // (null when ExportRequirements::frames or ::condition is false).
  const std::vector<cv::Mat>* condition = nullptr;
  // Each frame's source image (DriveFrame::image_path: a file, or an image
  // inside a container that ReadImageFile resolves).
  std::vector<std::string> image_paths;
  // True when `images` are the source images unchanged (the exporter's size
  // is the source's, nothing cropped): an exporter may then copy a source
  // JPEG's bytes (ReadImageFile) instead of encoding the frame again.
  bool images_are_source = false;
  // A video (H.264 MP4) already written of exactly `images`, at the pair
  // videos' preset and CRF and at the pair's --fps: the pair's gt.mp4 when
  // `images` are the pair's own frames (the exporter's size is the pair's);
  // empty otherwise. An exporter may link it instead of encoding the frames
  // again.
  std::string images_video;
  // The clip's condition scene, in the same frame as world_from_cam.
  const PointCloud* scene_cloud = nullptr;
  // With ExportRequirements::depth: the condition's z-depth per frame
  // (CV_32F, the scene's units, 0 = no point) and drawn mask (CV_8U, 255 = a
  // point was drawn); null otherwise.
  const std::vector<cv::Mat>* depth = nullptr;
  const std::vector<cv::Mat>* drawn = nullptr;
  // With ExportRequirements::native_condition: the renderer's frames before
  // the resize to the pair's size; null otherwise.
  const std::vector<cv::Mat>* native_condition = nullptr;
  // x264 preset and CRF of the pair's own videos (--x264-preset, --crf), for
  // an exporter that writes video.
  std::string video_preset = "ultrafast";
  int video_crf = 18;
  // Frame 0 at the source size (empty: read it from first_frame_path).
  cv::Mat first_frame_full;
  std::string first_frame_path;
  // Intrinsics at the exporter's size (integer-index pixel centres).
  PinholeCamera camera;
  // Pose of every frame in the scene frame (camera 0 at frame 0), OpenCV
  // axes.
  std::vector<Rigid3d> world_from_cam;
  // Capture time of every frame (the dataset's clock, microseconds).
  std::vector<int64_t> timestamps_us;
  // The dataset world's up (+z) in the export's world (unit).
  Eigen::Vector3d world_up = -Eigen::Vector3d::UnitY();
  // With ExportRequirements::lidar_frame_step: the sweeps at frames 0, s,
  // 2 s, ... below the frame count, in frame order; null otherwise. The
  // dataset's poses place them in the export's world (camera 0 at frame 0),
  // as they place the boxes.
  const std::vector<ExportSweep>* lidar = nullptr;
  // With ExportRequirements::objects: per frame, every annotated object at
  // the frame's time, all categories; null otherwise.
  const std::vector<std::vector<ExportObject>>* objects = nullptr;
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
  // Throws InputError "<clip_id>: <format> needs ..." when the exporter
  // cannot serve a clip of this id and length; by default the frame counts
  // of Requirements() (CheckClipForExport).
  virtual void CheckClip(const std::string& clip_id, int num_frames) const;
  // Writes the clip's files under `pair_dir` (the pair folder being built)
  // and records them in meta->files. Throws InputError naming the file.
  virtual void WriteClip(const ExportClip& clip,
                         const std::string& pair_dir,
                         PairMeta* meta) const = 0;
  // True when the format holds several cameras of a clip (build-dataset
  // --cameras): WriteRig then writes them.
  virtual bool WritesRigs() const { return false; }
  // Writes a rig pair's cameras (one ExportClip each, the reference camera
  // first, every pose in the rig's scene frame, ExportClip::channel set).
  // By default throws InputError: the format is single-camera.
  virtual void WriteRig(const std::vector<ExportClip>& views,
                        const std::string& pair_dir,
                        PairMeta* meta) const;
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
// when a clip of `num_frames` frames breaks `exporter`'s requirements (its
// frame counts; Exporter::CheckClip adds a format's own checks).
void CheckClipForExport(const Exporter& exporter,
                        const std::string& clip_id,
                        int num_frames);

}  // namespace geodrive
