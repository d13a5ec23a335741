#pragma once
// Other reconstruction tools' outputs read into MonST3R's conventions: a
// Monst3rFolder held in memory (geometry/monst3r.h) with world_from_cam poses
// (OpenCV axes), z-depth, integer-index pixel intrinsics on the tool's own
// grid, confidence in [0, 1] and the tool's resize of the source image, so
// everything downstream (LiDAR scale fit, pose refinement, the paper's
// filters, the condition render) is the MonST3R path unchanged.
//
// One reader per format (geometry/reconstruction/<format>.cc), created by
// CreateReconstructionReader. What each file holds and how it is converted:
// docs/RECONSTRUCTIONS.md; the facts come from each project's own writer
// (docs/reference/reconstruction_and_peer_formats.md section 1).

#include <cstdint>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "geometry/monst3r.h"

namespace geodrive {

enum class ReconstructionFormat {
  // A MonST3R output folder (pred_traj.txt, frame_NNNN.npy, conf_N.npy, ...).
  kMonst3r,
  // VGGT demo predictions.npz (extrinsic w2c (S,3,4), intrinsic, depth
  // (S,H,W,1), depth_conf 1 + exp(x), images (S,3,H,W) in [0, 1]).
  kVggt,
  // Depth Anything 3 results.npz (depth (N,H,W), conf, extrinsics w2c (N,3,4)
  // or (N,4,4), intrinsics (N,3,3), optional image (N,H,W,3) uint8).
  kDepthAnything3,
  // CUT3R's demo folder (depth/, conf/, color/, camera/ with pose c2w and
  // intrinsics per frame).
  kCut3r,
  // MegaSaM *_sgd_cvd_hr.npz / *_droid.npz (images, depths float16 or
  // float32, one intrinsic (3,3), cam_c2w (N,4,4)).
  kMegaSam,
  // MoGe / MoGe-2 --maps folder (depth.exr, points.exr, mask.png,
  // fov.json, image.jpg): one image, identity pose.
  kMoge,
  // Our generic npz: depth (N,H,W), optional conf with its stated scale,
  // intrinsics (N,3,3) or (3,3), cam_c2w or cam_w2c (N,4,4), optional images,
  // units. docs/RECONSTRUCTIONS.md has a five-line writer. The same name
  // reads our GEN3C export's clip folder (depth.npz, camera.npz, rgb.mp4:
  // dataset/export_gen3c.cc), recognized by its files.
  kGenericNpz,
};
// "monst3r", "vggt", "da3", "cut3r", "megasam", "moge", "npz".
std::string ToString(ReconstructionFormat format);
// Throws InputError listing the names for any other text.
ReconstructionFormat ParseReconstructionFormat(const std::string& text);
// Every format, in the order above.
std::vector<ReconstructionFormat> AllReconstructionFormats();

struct ReconstructionReadOptions {
  // Largest array accepted, in bytes, checked against the declared shape
  // before anything is allocated.
  uint64_t max_bytes = 8ull << 30;
  // Reject poses whose camera moves backwards along its optical axis at every
  // step (the signature of world_from_cam read as cam_from_world on a forward
  // driving clip). Off for footage that truly reverses.
  bool check_motion_direction = true;
  // Read the images where a format keeps them apart from the arrays (the
  // GEN3C export's rgb.mp4); false reads depth, poses and intrinsics only
  // (`geodrive info`, which decodes no video).
  bool images = true;
  // True when every field is in range.
  bool Check() const;
};

// How a format is converted (for `geodrive info` and docs/RECONSTRUCTIONS.md).
struct ReconstructionConventions {
  // Pose direction and matrix forms accepted, and what is done with them.
  std::string pose;
  // The tool's confidence scale and its mapping to [0, 1].
  std::string confidence;
  // Intrinsics form and the grid they are on (and the tool's resize).
  std::string intrinsics;
  // Units of depth and translation.
  std::string units;
};

class ReconstructionReader {
 public:
  virtual ~ReconstructionReader() = default;
  virtual ReconstructionFormat format() const = 0;
  // The tool's name as users know it ("VGGT").
  virtual std::string ToolName() const = 0;
  virtual ReconstructionConventions Conventions() const = 0;
  // The file the reader opens for `path` (the path itself, or the format's
  // file inside a folder); nullopt when `path` is not of this format. Looks
  // only at names and zip members, never at the arrays.
  virtual std::optional<std::string> Locate(const std::string& path) const = 0;
  // Reads the reconstruction at `path` (a file or a folder holding it).
  // Throws InputError naming the file, the array and what is wrong.
  virtual Monst3rFolder Read(
      const std::string& path,
      const ReconstructionReadOptions& options) const = 0;
};

// The frames of a video file, RGB CV_8UC3, for the formats that keep their
// images in one (the GEN3C export's rgb.mp4). `frames`, `width` and `height`
// are what the reconstruction's other files declare: the decoder checks the
// video's declared size and frame count against them before decoding and
// throws InputError naming the file when they differ. The geometry library
// decodes no video: the video module's decoder is set by the programs that
// link it (RegisterVideoDecoderForReconstructions, render/video/video_io.h;
// every scene source does); without one, reading such a format is an
// InputError saying so.
using ReconstructionVideoDecoder = std::function<std::vector<cv::Mat>(
    const std::string& path, int64_t frames, int width, int height)>;
// Sets the decoder for the process (thread-safe; a later call replaces it).
void SetReconstructionVideoDecoder(ReconstructionVideoDecoder decoder);
// The decoder set, or an empty function.
ReconstructionVideoDecoder GetReconstructionVideoDecoder();

std::unique_ptr<ReconstructionReader> CreateReconstructionReader(
    ReconstructionFormat format);
// The reader that reads `path` as `format`: CreateReconstructionReader(format),
// or the one that reader hands `path` to (a GEN3C export clip folder under
// kGenericNpz), for its ToolName() and Conventions().
std::unique_ptr<ReconstructionReader> CreateReconstructionReaderFor(
    ReconstructionFormat format, const std::string& path);
// The format of `path` (a file or a folder), or nullopt when none matches.
std::optional<ReconstructionFormat> DetectReconstructionFormat(
    const std::string& path);
// CreateReconstructionReader(format)->Read(path, options).
Monst3rFolder ReadReconstruction(ReconstructionFormat format,
                                 const std::string& path,
                                 const ReconstructionReadOptions& options = {});

}  // namespace geodrive
