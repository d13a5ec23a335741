#pragma once
// Reading a MonST3R output folder (demo.py / pose_eval.py layout; see
// docs/reference/formats_monst3r_nuscenes.md A.1-A.6) and raw pointmaps of
// other reconstruction models.
//
// Files of a folder with N frames (i = 0 .. N-1):
//   pred_traj.txt                  N lines `t x y z qw qx qy qz` (w FIRST),
//   world_from_cam pred_intrinsics.txt            N lines (or 1, shared)
//   row-major 3x3 K, processed-image pixels frame_%04d.npy float32 (H, W)
//   z-depth, MonST3R units (arbitrary scale) frame_%04d.png 8-bit RGB of the
//   network input (H x W) conf_{i}.npy                   float32 (H, W) log(raw
//   confidence); -inf where cleaned init_conf_{i}.npy              float32 (H,
//   W) log(raw confidence) before cleaning (optional) dynamic_mask_{i}.png
//   8-bit 0/255, 255 = dynamic (optional as a set)
//   enlarged_dynamic_mask_{i}.png  the same dilated 3x3 (optional as a set)
//   pts3d_{i}.npy                  float32 (H, W, 3) world pointmap (optional
//   as a set; not written
//                                  by MonST3R: the hook for other models' raw
//                                  pointmaps)
// Unpadded indices are parsed as the integer after the last '_' (never sorted
// as strings). Open() checks the whole file set and the frame counts; the pixel
// data are read lazily per frame.

#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/trajectory.h"

namespace geodrive {

// One frame's data. Matrices are empty when not loaded or absent.
struct Monst3rFrame {
  int index = -1;
  PinholeCamera camera;    // processed-image pixels, kIntegerIndex
  Rigid3d world_from_cam;  // from pred_traj.txt
  cv::Mat depth;           // CV_32FC1 z-depth (MonST3R units)
  cv::Mat rgb;             // CV_8UC3, RGB order
  cv::Mat log_confidence;  // CV_32FC1 conf_{i}.npy (may hold -inf)
  // CV_32FC1 confidence already in [0, 1]: other tools' reconstructions
  // (geometry/reconstruction.h), used when log_confidence is empty.
  cv::Mat confidence01;
  cv::Mat init_log_confidence;    // CV_32FC1 init_conf_{i}.npy
  cv::Mat dynamic_mask;           // CV_8UC1, 255 = dynamic
  cv::Mat enlarged_dynamic_mask;  // CV_8UC1, 255 = dynamic
  cv::Mat raw_points_in_world;    // CV_32FC3 pts3d_{i}.npy
};

// What LoadFrame reads (depth and pose are always read).
struct Monst3rLoadOptions {
  bool rgb = true;
  bool confidence = true;
  bool init_confidence = false;
  bool dynamic_masks = true;
  bool enlarged_dynamic_masks = true;
  bool raw_pointmaps = false;
  // Throw InputError when a confidence map is -inf (or NaN) everywhere.
  bool reject_all_invalid_confidence = true;
};

// How a reconstruction tool mapped the source image onto its pixel grid.
enum class GridResize {
  // DUSt3R's load_images(size=512) (MonST3R, CUT3R): long side to 512, each
  // side centre-cropped to a multiple of 16 (ComputeMonst3rResizeSpec).
  kMonst3r,
  // VGGT's load_and_preprocess_images (mode "crop"): width to 518, height to
  // round(h * 518 / w / 14) * 14 (a plain resize), then the height
  // centre-cropped to 518 when larger.
  kVggt,
  // The whole source image resized to the grid (per-axis scale; Depth
  // Anything 3, MegaSaM, MoGe, the generic npz).
  kStretch,
  // The source image centre-cropped to the grid's aspect and resized to it
  // (ComputeResizeSpec's kCenterCrop: the toolkit's trainer exports, e.g.
  // GEN3C's 1280x704).
  kCenterCrop,
};
std::string ToString(GridResize resize);
// The resize of a source image of in_width x in_height by `rule` (kStretch
// and kCenterCrop: an empty spec, as they need the grid: see
// Monst3rFolder::SourceToGrid).
ImageResizeSpec ComputeGridResizeSpec(GridResize rule,
                                      int in_width,
                                      int in_height);

// A MonST3R output folder; or any other tool's reconstruction converted to
// MonST3R's conventions and held in memory (FromFrames; the readers of
// geometry/reconstruction.h): world_from_cam poses in OpenCV axes,
// z-depth, integer-index pixels.
class Monst3rFolder {
 public:
  // Scans `dir`, reads pred_traj.txt and pred_intrinsics.txt, checks that every
  // per-frame file exists for frames 0..N-1 and that counts agree, and reads
  // the image size from the header of frame_0000.npy. Throws InputError naming
  // the file and the problem.
  static Monst3rFolder Open(const std::string& dir);
  // A reconstruction in memory. Every frame has depth (CV_32FC1, all the same
  // size), camera and world_from_cam; rgb (CV_8UC3), confidence01 and
  // dynamic_mask are optional but present in all frames or none. `name` is
  // the file or folder read (named in errors), `format` the tool ("VGGT"),
  // `units` "metres" when the tool's depth is metric (else empty: up to
  // scale). Throws InputError for inconsistent frames.
  static Monst3rFolder FromFrames(std::string name,
                                  std::string format,
                                  std::vector<Monst3rFrame> frames,
                                  GridResize resize,
                                  std::string units = "");

  const std::string& dir() const { return dir_; }
  int num_frames() const { return static_cast<int>(trajectory_.size()); }
  int width() const { return width_; }
  int height() const { return height_; }
  const Trajectory& trajectory() const { return trajectory_; }
  const std::vector<PinholeCamera>& cameras() const { return cameras_; }
  bool has_rgb() const { return has_rgb_; }
  bool has_confidence() const { return has_conf_; }
  bool has_init_confidence() const { return has_init_conf_; }
  bool has_dynamic_masks() const { return has_masks_; }
  bool has_enlarged_dynamic_masks() const { return has_enlarged_masks_; }
  bool has_raw_pointmaps() const { return has_pts3d_; }
  // The tool that wrote it: "MonST3R" for Open(), else FromFrames' format.
  const std::string& format() const { return format_; }
  // "metres" when the depth is metric as read, empty when up to scale.
  const std::string& units() const { return units_; }
  // How the tool mapped a source image onto the grid (kMonst3r for Open()).
  GridResize grid_resize() const { return grid_resize_; }
  // True for FromFrames (no per-frame files: the *Path() functions return
  // empty strings).
  bool in_memory() const { return memory_ != nullptr; }
  // The resize from a source image of in_width x in_height to this grid
  // (per grid_resize(); its width and height may differ from the grid's when
  // the source is not the tool's input).
  ImageResizeSpec SourceToGrid(int in_width, int in_height) const;

  // File paths of frame i (empty for an in-memory reconstruction).
  std::string DepthPath(int i) const;
  std::string RgbPath(int i) const;
  std::string ConfidencePath(int i) const;
  std::string InitConfidencePath(int i) const;
  std::string DynamicMaskPath(int i) const;
  std::string EnlargedDynamicMaskPath(int i) const;
  std::string RawPointmapPath(int i) const;

  // Reads frame i. Shapes must all equal (height, width); throws InputError
  // otherwise (naming the file), and for an all -inf confidence map when
  // options.reject_all_invalid_confidence.
  Monst3rFrame LoadFrame(int i, const Monst3rLoadOptions& options = {}) const;
  // Reads the listed frames (OpenMP-parallel over frames).
  std::vector<Monst3rFrame> LoadFrames(
      const std::vector<int>& indices,
      const Monst3rLoadOptions& options = {}) const;

 private:
  std::string dir_;
  std::string format_ = "MonST3R", units_;
  GridResize grid_resize_ = GridResize::kMonst3r;
  std::shared_ptr<const std::vector<Monst3rFrame>> memory_;
  int width_ = 0, height_ = 0;
  Trajectory trajectory_;
  std::vector<PinholeCamera> cameras_;
  bool has_rgb_ = false, has_conf_ = false, has_init_conf_ = false,
       has_masks_ = false, has_enlarged_masks_ = false, has_pts3d_ = false;
  // Frame index -> file name as found by the scan.
  std::map<int, std::string> names_depth_, names_rgb_, names_conf_, names_init_,
      names_mask_, names_enl_, names_pts_;
};

// Parses a frame list "0..24", "0,3,5", "2..10:2" (start..end inclusive[:step])
// or "all" for a clip of `num_frames` frames. Throws InputError for indices out
// of range or bad syntax.
std::vector<int> ParseFrameList(const std::string& text, int num_frames);

// How a raw confidence file is encoded.
enum class ConfidenceEncoding {
  kLog,   // log(raw), raw in (1, inf): MonST3R conf_*.npy
  kRaw,   // raw in (1, inf): DUSt3R/MonST3R network output (real-time mode
          // conf*_p*.npy)
  kUnit,  // already in [0, 1]
};

// Maps one confidence value to [0, 1]. kLog: raw = exp(v), conf01 = 1 - 1/raw =
// 1 - exp(-v) (so -inf -> 0, 0 -> 0, log 3 -> 2/3; tau = 0.65 <-> v = -ln 0.35
// = 1.0498). kRaw: 1 - 1/raw (raw <= 1 -> 0). kUnit: clamped to [0, 1]. NaN ->
// 0.
float ConfidenceToUnit(float value,
                       ConfidenceEncoding encoding = ConfidenceEncoding::kLog);
// Elementwise over a CV_32FC1 map.
cv::Mat ConfidenceMapToUnit(
    const cv::Mat& confidence,
    ConfidenceEncoding encoding = ConfidenceEncoding::kLog);

// A raw pointmap from any reconstruction model: world points per pixel plus
// confidence.
struct RawPointmap {
  cv::Mat points_in_world;  // CV_32FC3
  cv::Mat confidence01;     // CV_32FC1 in [0, 1] (empty if no confidence file)
  cv::Mat rgb;  // CV_8UC3 (from an (H, W, 6) file with rgb in [0, 1], or empty)
};
// Reads an (H, W, 3) or (H, W, 6) (xyz + rgb in [0, 1]) float .npy and an
// optional (H, W) confidence .npy (empty path = none), converting the
// confidence to [0, 1].
RawPointmap ReadRawPointmap(
    const std::string& points_path,
    const std::string& confidence_path = "",
    ConfidenceEncoding encoding = ConfidenceEncoding::kLog);

}  // namespace geodrive
