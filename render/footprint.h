#pragma once
// Footprint-aware splats (issue 22). A point of a pointmap stands for the
// pixel that saw it: at capture depth z0 with a focal length of f0 pixels that
// pixel is a square of side
//     s = z0 / f0                    (PointCloud::footprints; f = sqrt(fx fy))
// in the cloud's units. Seen at depth z by a camera of focal length f, it
// covers L = s f / z pixels (its magnification). Drawn as one pixel, a
// magnified surface shows holes through which the background bleeds; the
// z-buffer renderer (SplatSize::kFootprint) therefore draws such a point as a
// disk of radius
//     r = min(L, L_max) * sqrt(2) / 2    when L > 1.05, one pixel otherwise,
// the disk through the corners of its L x L square, so that neighbours seen at
// the same magnification leave no gap; L_max caps the blur of points seen far
// closer than at capture. The footprint is isotropic (the point's capture
// pixel area, its depth then and now): a surface seen at a grazing angle, the
// road ahead, stretches along the view by more than L as it is approached and
// may still show gaps between its rows. The 5 % margin keeps a point seen as at
// capture (L = 1 up to float rounding) at one pixel, the paper's behaviour. The
// depth test is the usual one (nearest wins, ties to the smaller index), so the
// result does not depend on the order of the points or the thread count. The
// dynamic editor's moved objects (drawn larger when approached or scaled) carry
// footprints too and are drawn by the same rule: one mechanism.

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

// Sets cloud->footprints from the camera that captured the cloud (its
// positions are in the world; cam_from_world is that camera's pose).
void SetCaptureFootprints(const PinholeCamera& camera,
                          const Rigid3d& cam_from_world,
                          PointCloud* cloud);

// The squared z-buffer splat radius in pixels² of a point with footprint `s`
// at depth `z` seen with focal length `focal` (pixels): 0 (one pixel) unless
// magnified (L = s focal / z > 1.05), otherwise min(L, max_magnification)² / 2
// (squared, so that L = 2 reaches the diagonal neighbours exactly).
inline float FootprintRadius2(float s,
                              float focal,
                              float z,
                              float max_magnification) {
  float l = s * focal / z;
  if (!(l > 1.05f) || !(max_magnification > 1.0f)) return 0.0f;
  if (l > max_magnification) l = max_magnification;
  return 0.5f * l * l;
}

}  // namespace geodrive
