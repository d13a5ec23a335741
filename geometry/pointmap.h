#pragma once
// Per-frame world pointmaps and their filters (GeoDrive §3.1: confidence
// threshold, depth range, static/dynamic split).
//
// Pixel convention: MonST3R's own (optimizer.py:_fast_depthmap_to_pts3d): pixel
// (u = column index, v = row index) unprojects at the INTEGER index, no +0.5
// (PixelConvention::kIntegerIndex):
//   X_cam = ((u - cx) d / fx, (v - cy) d / fy, d),  X_world = world_from_cam *
//   X_cam.

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/monst3r.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"

namespace geodrive {

// One frame's pointmap: H x W maps, row-major pixels (v, u).
struct Pointmap {
  int frame_index = -1;
  PinholeCamera camera;
  Rigid3d world_from_cam;
  cv::Mat points_in_world;  // CV_32FC3 (NaN where the depth is not finite)
  cv::Mat depth;  // CV_32FC1 z-depth in camera units (MonST3R units or metres)
  cv::Mat confidence;  // CV_32FC1 in [0, 1] (empty = unknown: confidence filter
                       // skipped)
  cv::Mat dynamic_mask;           // CV_8UC1 255 = dynamic (empty = none)
  cv::Mat enlarged_dynamic_mask;  // CV_8UC1 255 = dynamic (empty = none)
  cv::Mat rgb;                    // CV_8UC3 RGB (empty = no colour)

  int width() const { return depth.cols; }
  int height() const { return depth.rows; }
};

// Which confidence map of a MonST3R frame to use.
enum class ConfidenceSource { kConf, kInitConf };

// Builds the world pointmap of a MonST3R frame from depth, K and pose
// (integer-index pixels). `depth_scale` multiplies depth and pose translation
// (1 = MonST3R units; the metres-per-unit factor once the scale is known).
// Confidence is mapped with ConfidenceToUnit(kLog).
Pointmap BuildPointmap(const Monst3rFrame& frame,
                       double depth_scale = 1.0,
                       ConfidenceSource source = ConfidenceSource::kConf);
// A pointmap from raw world points (other reconstruction models): depth is the
// z of each point in the camera given by `world_from_cam` (identity if the
// points are in camera coordinates).
Pointmap PointmapFromRawPoints(const RawPointmap& raw,
                               const PinholeCamera& camera,
                               const Rigid3d& world_from_cam,
                               int frame_index = 0);

// Which pixels a filter keeps with respect to the dynamic masks.
enum class PixelSelection { kAll, kStaticOnly, kDynamicOnly };
// Which dynamic mask decides static/dynamic.
enum class DynamicMaskKind { kPlain, kEnlarged };

struct PointmapFilterOptions {
  // Minimum confidence in [0, 1] (conf01 = 1 - 1/raw, raw = exp(log-conf);
  // paper tau = 0.65). Pixels with -inf log-confidence map to 0 and are always
  // dropped when this is > 0.
  double min_confidence = 0.65;
  // Depth range, in the pointmap's units: metres once a scale is known
  // (BuildPointmap's depth_scale), otherwise MonST3R units. Paper: 0.1 - 100 m.
  double min_depth = 0.1;
  double max_depth = 100.0;
  // Static/dynamic split and the mask that decides it. Frames without masks
  // count as all static.
  PixelSelection selection = PixelSelection::kAll;
  DynamicMaskKind mask_kind = DynamicMaskKind::kEnlarged;
  // Keep every stride-th pixel in u and v (1 = all).
  int stride = 1;

  // Throws InputError naming the bad field.
  void Check() const;
};

// Why pixels were dropped (each pixel is counted once, by the first failing
// test in this order).
struct PointmapFilterStats {
  int64_t total = 0;         // pixels considered (after stride)
  int64_t non_finite = 0;    // non-finite depth or point
  int64_t out_of_range = 0;  // depth outside [min_depth, max_depth]
  int64_t low_confidence = 0;
  int64_t masked = 0;  // excluded by the static/dynamic selection
  int64_t kept = 0;

  void Add(const PointmapFilterStats& other);
  std::string ToString() const;
};

// CV_8UC1 mask (255 = keep) of the pixels that pass the filters.
cv::Mat ComputeValidMask(const Pointmap& pointmap,
                         const PointmapFilterOptions& options,
                         PointmapFilterStats* stats = nullptr);

// Where a point came from: frame index and integer pixel (u = column, v = row).
struct PointProvenance {
  int32_t frame = -1;
  int16_t u = -1, v = -1;
};

// The kept points as a cloud (positions in world, colours when the pointmap has
// rgb, confidence when known). `provenance`, if non-null, receives one entry
// per point. `depths`, if non-null, receives each point's camera depth.
PointCloud ExtractPoints(const Pointmap& pointmap,
                         const cv::Mat& valid_mask,
                         std::vector<PointProvenance>* provenance = nullptr,
                         std::vector<float>* depths = nullptr);

// A single 3x3 K from a text file: 9 numbers in any whitespace layout (a
// MonST3R pred_intrinsics.txt line, or 3 rows of 3); with 9*N numbers the first
// K is used. Throws InputError naming the file for a missing file, a token that
// is not a number, a count that is not a multiple of 9, or a K that is not
// [[fx,0,cx],[0,fy,cy],[0,0,1]] with finite values and positive focals.
PinholeCamera ReadIntrinsicsFile(const std::string& path,
                                 int width,
                                 int height);

// A z-depth map from an .npy of shape (H, W) (leading/trailing axes of size 1
// are dropped), as CV_32F. Throws InputError naming the file otherwise.
cv::Mat ReadDepthNpy(const std::string& path);

// Every pixel of a z-depth map (CV_32F) with finite positive depth, unprojected
// at its integer index (as MonST3R) and moved by `world_from_cam`, coloured by
// `rgb` (CV_8UC3 RGB, same size) — a single image + depth as a renderable
// cloud.
PointCloud CloudFromDepth(const cv::Mat& depth,
                          const cv::Mat& rgb,
                          const PinholeCamera& camera,
                          const Rigid3d& world_from_cam);

}  // namespace geodrive
