#pragma once
// Footprint-aware splats. A point of a pointmap stands for the
// pixel that saw it. Drawn as one pixel, a surface seen from closer than at
// capture shows holes through which the background bleeds; the z-buffer
// renderer (SplatSize::kFootprint) therefore draws each point over the
// bounding box of its capture pixel as seen now.
//
// The capture pixel of a point is described two ways (PointCloud):
//  - footprints: the side s = z0 / f0 of the pixel at the capture depth z0
//    with a focal length of f0 = sqrt(fx fy) pixels (a camera-facing square).
//    Seen at depth z with focal length f it covers L = s f / z pixels (its
//    magnification): the splat is the L x L square around the projection.
//  - footprint_u, footprint_v: where the point lies on a surface of the
//    capture's depth map, the surface's displacement per capture pixel along
//    x and y (central differences of the neighbouring pixels' points). Seen
//    now, these project to pixel vectors a and b (through the projection's
//    Jacobian); the splat is the parallelogram's bounding box, half-extents
//    (|a_x| + |b_x|) / 2 and (|a_y| + |b_y|) / 2. This follows the surface's
//    slope: the road ahead, seen at a grazing angle, stretches along the view
//    by about the square of the approach ratio as the car nears it, which the
//    camera-facing square does not know.
// A splat covers the pixels whose centres lie in the box (edges included;
// each half-extent at least 0.5, so the box holds a pixel centre), so
// neighbours seen at the same magnification tile the image without gaps or
// overlaps. A point is drawn as one pixel (the paper) unless a half-extent
// exceeds 0.525 (magnification 1.05: the 5 % margin keeps a point seen as at
// capture, up to rounding, at one pixel); half-extents are capped at
// max_magnification / 2 so that a point seen far closer than at capture does
// not become a large blur. The depth test is the usual one (nearest wins,
// ties to the smaller index): the result does not depend on the order of the
// points or the thread count. The dynamic editor's moved objects (drawn larger
// when approached or scaled) carry footprints too and are drawn by the same
// rule: one mechanism.

#include <Eigen/Core>
#include <cmath>
#include <vector>

#include "geometry/camera.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"

namespace geodrive {

// Footprint side s = z / sqrt(fx fy) of a point at camera depth z (0 when the
// point is not in front of the camera: unknown, drawn as one pixel).
inline float CaptureFootprint(const PinholeCamera& camera, double z) {
  return z > 0 ? static_cast<float>(z / std::sqrt(camera.fx * camera.fy))
               : 0.0f;
}

// Sets cloud->footprints (and, with `surface_axes`, footprint_u/v) from the
// camera that captured the cloud (positions in the world; cam_from_world is
// that camera's pose). The axes come from the cloud's own depth map on the
// camera's grid (the nearest point per pixel, rounded to the integer-index
// pixel): a point that is the nearest at its pixel gets the surface's
// displacement per pixel along x and y — the central difference of its
// neighbours where the three lie on a plane (inverse depth affine in the
// pixel: any slope), else the one-sided difference to a neighbour within 5 %
// of its depth (creases, edges) — each axis at most 64 s long; the others
// (isolated returns, points outside the grid, no neighbour on the surface)
// get zero axes and are drawn with s.
void SetCaptureFootprints(const PinholeCamera& camera,
                          const Rigid3d& cam_from_world,
                          PointCloud* cloud,
                          bool surface_axes = true);

// The splat's half-extents (pixels) of a camera-facing footprint `s` at depth
// `z` seen with focal length `focal`: 0 (one pixel) unless magnified (L = s
// focal / z > 1.05), otherwise min(L, max_magnification) / 2.
inline float FootprintHalfExtent(float s,
                                 float focal,
                                 float z,
                                 float max_magnification) {
  float l = s * focal / z;
  if (!(l > 1.05f) || !(max_magnification > 1.0f)) return 0.0f;
  if (l > max_magnification) l = max_magnification;
  return 0.5f * l;
}

}  // namespace geodrive
