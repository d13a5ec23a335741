#pragma once
// Point splatting renderer: a coloured cloud seen through a pinhole camera per
// frame.
//
// Two modes:
//  - kZBuffer (the paper, §3.2): keep near < z < far, splat each point as a
//  disk of
//    `radius_px` pixels (0 = the single pixel that contains the projection),
//    nearest depth wins. Ties in depth are broken by the smaller point index,
//    so the output does not depend on the processing order.
//  - kSoft (the released model): PyTorch3D `PointsRasterizer` +
//  `AlphaCompositor`. The radius is
//    in NDC units where the SHORT image side spans 2 (one pixel = 2 / min(W, H)
//    NDC on both axes; the long side spans 2 * max/min). A point hits a pixel
//    if its squared NDC distance d² to the pixel centre is < r² and z > 0
//    (PyTorch3D keeps z >= 0; we also apply near/far when they are set, see
//    RenderOptions). The K nearest hits by (z, point index) are sorted front to
//    back and composited with w_k = 1 - d_k² / r²:
//        C = Σ_k w_k Π_{j<k} (1 - w_j) c_k,   black background.
//
// Pixel centres. With PixelConvention::kIntegerIndex, pixel column i has its
// centre at the continuous coordinate u = i (OpenCV, MonST3R unprojection): a
// pointmap unprojected from integer pixel indices renders back onto exactly its
// own pixels. With kPixelCenter, pixel i's centre is at u = i + 0.5. PyTorch3D
// puts pixel i's centre at NDC -(S/s)(1 - (2i + 1)/S) (S = that side's length,
// s = min(W, H)), and a `PerspectiveCameras(in_ndc=False)` camera maps the
// screen coordinate u = fx X / Z + cx to NDC (W/2 - u) / (s/2) (x flipped);
// equating the two gives u = i + 0.5, i.e. the released pipeline interprets
// MonST3R's K in the kPixelCenter convention (a half-pixel shift with respect
// to how the pointmap was unprojected). The `geodrive-compat` preset therefore
// uses kPixelCenter; everything else defaults to kIntegerIndex.
//
// Threads: frames are rendered in parallel (OpenMP, one frame per thread at a
// time); every frame is computed by the same sequential code whatever the
// thread count, so the output is byte-identical for 1 or N threads.

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"

namespace geodrive {

enum class RenderMode { kZBuffer, kSoft };
std::string ToString(RenderMode mode);
// Parses "zbuffer" or "soft"; throws InputError otherwise.
RenderMode ParseRenderMode(const std::string& text);

// How large a z-buffer splat is (render/footprint.h).
enum class SplatSize {
  // Every point with `radius_px` (the paper: 0, one pixel).
  kFixed,
  // A point seen from closer than at capture covers its magnified capture
  // pixel: radius from PointCloud::footprints, its depth now and the focal
  // length now, capped at `max_footprint_magnification`; never below
  // `radius_px`.
  kFootprint,
};
std::string ToString(SplatSize size);
// Parses "fixed" or "footprint"; throws InputError otherwise.
SplatSize ParseSplatSize(const std::string& text);

struct RenderOptions {
  RenderMode mode = RenderMode::kZBuffer;
  // Output size. Cameras whose size differs are rescaled to it (ResizeCamera,
  // in `pixel_convention`).
  int width = 720;
  int height = 480;
  // Valid depth range (camera z, units of the cloud): near < z < far. The paper
  // uses 0.1..100 m. In soft mode PyTorch3D only drops z < 0; set near = 0, far
  // = +inf to match it exactly.
  double near = 0.1;
  double far = 100.0;
  // kZBuffer: splat radius in pixels (0 = one pixel; otherwise every pixel
  // whose centre lies within the radius of the projection, i.e. a disk).
  double radius_px = 0.0;
  // kZBuffer: fixed radius or capture footprints. With kFootprint, a static
  // cloud without footprints is taken as captured by frame 0's camera (so
  // frame 0 draws one pixel per point). Points of moving point sets that
  // carry footprints use them in either setting (the dynamic editor's
  // magnified objects).
  SplatSize splat_size = SplatSize::kFixed;
  // Footprint splats: the largest magnification drawn (radius cap
  // max * sqrt(2) / 2 pixels), in [1, 16]; 1 = one pixel per point.
  double max_footprint_magnification = 3.0;
  // kSoft: splat radius in NDC units (short side spans 2) and points kept per
  // pixel (1..32).
  double radius_ndc = 0.01;
  int points_per_pixel = 10;
  // Where pixel centres are with respect to the camera's cx, cy (see the file
  // comment).
  PixelConvention pixel_convention = PixelConvention::kIntegerIndex;
  // kZBuffer only: fill holes after splatting (off by default, as in the
  // paper). Each of `hole_fill_iterations` passes gives every invalid pixel
  // with at least `hole_fill_min_neighbors` valid 8-neighbours the colour,
  // depth and index of its nearest-depth valid neighbour (ties: smaller point
  // index). Filled pixels are marked kMaskFilled in the mask.
  bool hole_fill = false;
  int hole_fill_iterations = 2;
  int hole_fill_min_neighbors = 3;
  // Extra outputs.
  bool output_index = false;  // per-pixel point index (CV_32S, -1 = none)
  bool output_instance =
      false;  // per-pixel instance id (CV_32S, -1 = none / background)
  bool output_float_rgb = false;  // RGB in [0, 1] before rounding (CV_32FC3)
  // Threads for RenderFrames (0 = OpenMP default). The result does not depend
  // on it.
  int num_threads = 0;

  // Throws InputError on an invalid combination (size 0 or > 16384, K out of
  // range, ...).
  void Check() const;
};

// Mask values.
constexpr uint8_t kMaskInvalid = 0;
constexpr uint8_t kMaskFilled = 128;  // hole-filled pixel (zbuffer + hole_fill)
constexpr uint8_t kMaskValid = 255;

struct RenderedFrame {
  cv::Mat rgb;    // CV_8UC3, RGB order, black where invalid
  cv::Mat depth;  // CV_32F, camera z of the front-most point, 0 where invalid
  cv::Mat mask;   // CV_8U, kMaskValid / kMaskFilled / kMaskInvalid
  cv::Mat index;  // CV_32S point index (front-most), -1 = none; only if
                  // output_index
  cv::Mat instance;   // CV_32S instance id, -1 = none; only if output_instance
  cv::Mat rgb_float;  // CV_32FC3 in [0, 1]; only if output_float_rgb
  int64_t num_valid =
      0;  // pixels hit by at least one point (filled pixels not included)
  int64_t num_filled = 0;     // pixels filled by hole filling
  int64_t num_projected = 0;  // points inside near/far and the image
  double coverage() const;    // num_valid / (W * H)
};

struct RenderSummary {
  int num_frames = 0;
  int64_t num_points = 0;
  double mean_coverage = 0, min_coverage = 0, max_coverage = 0;
  std::vector<int>
      empty_frames;  // frames where no point was visible (all-invalid)
  double seconds = 0;
  std::string BriefReport() const;
};

struct RenderResult {
  std::vector<RenderedFrame> frames;
  RenderSummary summary;
};

// Renders one frame. Throws InputError on bad input (empty cloud, non-finite
// positions, invalid camera, invalid pose). A frame where nothing is visible is
// returned all-invalid.
RenderedFrame RenderFrame(const PointCloud& cloud_in_world,
                          const PinholeCamera& camera,
                          const Rigid3d& cam_from_world,
                          const RenderOptions& options = {});

// Renders one frame per pose. `cameras` holds one camera for all frames or one
// per pose.
RenderResult RenderFrames(const PointCloud& cloud_in_world,
                          const std::vector<PinholeCamera>& cameras,
                          const std::vector<Rigid3d>& cam_from_world,
                          const RenderOptions& options = {});

// Same, reusing the buffers already in `result` (frames of the same size and
// options are overwritten in place; use this in loops to avoid re-allocating
// and page-faulting outputs).
void RenderFramesInto(const PointCloud& cloud_in_world,
                      const std::vector<PinholeCamera>& cameras,
                      const std::vector<Rigid3d>& cam_from_world,
                      const RenderOptions& options,
                      RenderResult* result);

// A point set that moves rigidly (or with a per-axis scale) from frame to
// frame, e.g. a vehicle: its points in its own frame and, per frame, the
// affine map world_from_set = [A | t] (x_world = A x_set + t); nullopt = not
// drawn in that frame.
struct MovingPointSet {
  PointCloud points;         // in the set's frame (instance_ids ignored)
  int32_t instance_id = -1;  // written to the instance output for its points
  std::vector<std::optional<Matrix3x4d>> world_from_set;  // one per frame
};

// Renders a static cloud plus moving point sets, in one depth test per frame:
// the result equals rendering, per frame, the static cloud (less the points in
// `hidden_static`) concatenated with every drawn set mapped to the world (up to
// the float rounding of the composed transform; with identity transforms the
// bytes are the same). Point indices (output_index): static points keep their
// index 0..S-1, then come the sets' points in order (set k starts after all
// points of sets 0..k-1, drawn or not), so depth ties go to static points,
// then to earlier sets. `hidden_static` (ascending, unique, < S) lists static
// points left out, e.g. the source points of objects that now move. Everything
// is validated and packed once per call; per frame a set costs only the
// projection of its points. The static points' instance output is the static
// cloud's instance_ids (-1 without). The static cloud may be empty. Throws
// InputError on bad input.
void RenderFramesWithMovingSets(const PointCloud& static_cloud,
                                const std::vector<MovingPointSet>& sets,
                                const std::vector<PinholeCamera>& cameras,
                                const std::vector<Rigid3d>& cam_from_world,
                                const RenderOptions& options,
                                RenderResult* result,
                                const std::vector<size_t>& hidden_static = {});

// Estimated bytes a render holds at its peak: `frames_held` output frames
// (RenderedFrame with the outputs `options` asks for) plus, for each of
// `threads` threads, the per-pixel and per-point scratch of the mode, plus the
// packed cloud of `num_points` points. Callers compare it with
// AvailableMemoryBytes() (geometry/util/memory.h) to refuse a job that cannot
// fit instead of dying on std::bad_alloc, and to choose how many frames to
// hold when streaming.
uint64_t EstimateRenderBytes(const RenderOptions& options,
                             int64_t num_points,
                             int frames_held,
                             int threads);
// The output bytes of one rendered frame (part of EstimateRenderBytes).
uint64_t RenderedFrameBytes(const RenderOptions& options);

// Testing hook: enables or disables the AVX2 splat kernels (on by default
// where the CPU has AVX2). Both paths give byte-identical output; returns the
// previous setting.
bool SetRendererSimdEnabled(bool enabled);

// Testing hook: enables or disables the frustum culling of point groups in the
// radius-0 z-buffer path (on by default). Culling only skips points the
// per-point test rejects, so the output is the same; returns the previous
// setting.
bool SetRendererCullingEnabled(bool enabled);

// Throws InputError("<what>: ...") if the pose has NaN/Inf or a rotation that
// is not orthonormal (quaternion norm off by more than `tol`).
void CheckPose(const Rigid3d& pose, const std::string& what, double tol = 1e-6);

}  // namespace geodrive
