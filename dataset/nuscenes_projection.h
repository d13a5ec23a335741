#pragma once
// nuScenes projections, exact to the devkit (part of the nuScenes adapter):
//  - LiDAR -> image of sample_data rows (the generic five-transform chain is
//    dataset/lidar_projection.h);
//  - 3D box -> 2D box as `scripts/export_2d_annotations_as_json.py` (corners
//  with z > 0, convex hull
//    of their projections intersected with the canvas [0, W] x [0, H],
//    min/max);
//  - `geometry_utils.box_in_image` (ANY / ALL / NONE visibility).
// Pixels are kIntegerIndex (nuScenes K, no +0.5), as the devkit's view_points.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "dataset/lidar_projection.h"
#include "dataset/nuscenes.h"
#include "geometry/rigid3.h"
#include "render/boxes.h"

namespace geodrive {

// Dataset convenience: projects the LiDAR sample_data `lidar_sd`'s cloud
// (already loaded, in its sensor frame) into camera sample_data `cam_sd`, each
// with its own ego pose.
LidarProjection MapPointCloudToImage(
    const Nuscenes& nusc,
    const std::vector<Eigen::Vector3f>& points_in_lidar,
    int32_t lidar_sd,
    int32_t cam_sd,
    const LidarProjectionOptions& options = {});

// 2D boxes [xmin, ymin, xmax, ymax] in pixels are render/boxes.h's Box2d (one
// type project-wide).
double IoU(const Box2d& a, const Box2d& b);

// Devkit `post_process_coords`: convex hull of the points intersected with [0,
// W] x [0, H]; the min/max of the intersection, or nullopt if they do not
// intersect. Degenerate hulls (1 or 2 points) are clipped as a point / segment.
std::optional<Box2d> PostProcessCoords(
    const std::vector<Eigen::Vector2d>& points, int width, int height);

// Devkit 2D export of a box given in the camera frame: the corners with z > 0,
// projected with K, then PostProcessCoords. nullopt if no corner is in front or
// the hull misses the canvas.
std::optional<Box2d> BoxTo2d(const NuscenesBox& box_in_cam,
                             const Eigen::Matrix3d& K,
                             int width,
                             int height);

// Devkit `get_2d_boxes` for one camera sample_data: each annotation's global
// box moved into the camera frame through that sample_data's own ego pose.
// Boxes of sweeps are interpolated (Nuscenes::GetBoxes). Returns the box
// (camera frame) and its 2D box, for the boxes kept.
struct CameraBox {
  NuscenesBox box_in_cam;
  Box2d box_2d;
};
std::vector<CameraBox> CameraBoxes2d(const Nuscenes& nusc, int32_t cam_sd);

enum class BoxVisibility { kAll, kAny, kNone };

// Devkit `box_in_image`: a corner is visible when 0 < u < W, 0 < v < H and z >
// 1; kAll needs all 8, kAny at least one, kNone is always true.
bool BoxInImage(const NuscenesBox& box_in_cam,
                const Eigen::Matrix3d& K,
                int width,
                int height,
                BoxVisibility visibility = BoxVisibility::kAny);

}  // namespace geodrive
