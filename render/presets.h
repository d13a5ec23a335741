#pragma once
// Render presets.
//  - paper: z-buffer splatting as in the paper (§3.2): 480x720, one pixel per
//  point,
//    0.1 < z < 100, no hole filling.
//  - geodrive-compat: the released GeoDrive data engine (ViewCrafter
//  pvd_utils): PyTorch3D soft
//    rasterisation at 512x288, radius 0.01 NDC, K = 10, z > 0 (no near/far
//    clip), the camera's cx, cy read as PyTorch3D screen coordinates
//    (kPixelCenter), then bilinear x2 upsampling (align_corners=False) to
//    1024x576 and frame 0 replaced by the real image when given.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "render/renderer.h"

namespace geodrive {

//  - footprint: the paper's z-buffer with footprint-aware splats
//    (render/footprint.h): a point seen from closer than at capture covers its
//    magnified capture pixel (at most 8x: the road just ahead of the car is
//    stretched along the view by up to (z0 / z)²), so approached surfaces
//    keep no holes; seen as at capture, one pixel per point as in paper.
enum class RenderPreset { kPaper, kGeodriveCompat, kFootprint };
std::string ToString(RenderPreset preset);
// "paper", "geodrive-compat" or "footprint"; throws InputError otherwise.
RenderPreset ParseRenderPreset(const std::string& text);

// Renderer options of a preset.
RenderOptions PresetRenderOptions(RenderPreset preset);
// Upsampling factor the preset applies after rendering (1 = none).
int PresetUpsampleFactor(RenderPreset preset);

// The final RGB frames of a rendered clip under a preset: for geodrive-compat,
// the float render is bilinearly upsampled by the factor (align_corners=False)
// and rounded, and frame 0 is replaced by `real_frame0_rgb` (resized bilinearly
// to the output size) when it is non-empty. For paper, the frames are returned
// as rendered (frame 0 replaced only if `real_frame0_rgb` is given).
std::vector<cv::Mat> FinalFrames(const RenderResult& result,
                                 RenderPreset preset,
                                 const cv::Mat& real_frame0_rgb = cv::Mat());

}  // namespace geodrive
