#pragma once
// Pinhole camera model and the exact intrinsics changes for resize and crop.
//
// Pixel conventions (always named, never implied):
//  - kIntegerIndex: pixel (col i, row j) has its centre at continuous coordinate (i, j). This is
//    OpenCV's and MonST3R's convention (MonST3R unprojects integer indices with no +0.5) and the one
//    nuScenes intrinsics use.
//  - kPixelCenter: pixel (i, j) covers [i, i+1) x [j, j+1) and its centre is at (i + 0.5, j + 0.5)
//    (OpenGL / PyTorch3D-style continuous image coordinates).
// Project() returns coordinates in the requested convention; Unproject() takes them.

#include <Eigen/Core>
#include <string>

namespace geodrive {

enum class PixelConvention { kIntegerIndex, kPixelCenter };

struct PinholeCamera {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;

  PinholeCamera() = default;
  PinholeCamera(double fx, double fy, double cx, double cy, int width, int height);
  // From a 3x3 K (row-major [[fx,0,cx],[0,fy,cy],[0,0,1]]); K's cx, cy are kIntegerIndex.
  static PinholeCamera FromK(const Eigen::Matrix3d& K, int width, int height);
  Eigen::Matrix3d K() const;

  // True if focal lengths are positive and finite and the size is positive and <= 16384.
  bool IsValid() const;
  // Throws InputError naming `what` if !IsValid().
  void Check(const std::string& what = "camera") const;

  // Projects a point in camera coordinates (z forward) to pixel coordinates in `convention`.
  // The caller checks z > 0.
  Eigen::Vector2d Project(const Eigen::Vector3d& point_in_cam,
                          PixelConvention convention = PixelConvention::kIntegerIndex) const;
  // Unprojects pixel coordinates (in `convention`) at z-depth `depth` to camera coordinates.
  Eigen::Vector3d Unproject(const Eigen::Vector2d& pixel, double depth,
                            PixelConvention convention = PixelConvention::kIntegerIndex) const;
  // True if the pixel (kIntegerIndex) lies inside [-0.5, W-0.5) x [-0.5, H-0.5).
  bool InImage(const Eigen::Vector2d& pixel) const;
};

// Exact intrinsics after resizing the image to new_width x new_height (independent x/y scale).
// For kIntegerIndex intrinsics (the default, OpenCV/nuScenes) pixel centres map as
// u' + 0.5 = (u + 0.5) * sx, so cx' = (cx + 0.5) * sx - 0.5. With kPixelCenter, cx' = cx * sx.
PinholeCamera ResizeCamera(const PinholeCamera& camera, int new_width, int new_height,
                           PixelConvention convention = PixelConvention::kIntegerIndex);
// Intrinsics after cropping the window [left, left+width) x [top, top+height): cx' = cx - left.
PinholeCamera CropCamera(const PinholeCamera& camera, int left, int top, int width, int height);

// How an image of one size is brought to a target size.
enum class ResizeMode {
  kResize,      // plain, aspect-distorting resize (GeoDrive training: 1600x900 -> 720x480)
  kCenterCrop,  // resize so the target is covered (round), then centre-crop (GeoDrive inference)
};
// The geometric description of a resize-then-crop: resize to (resized_width, resized_height), then
// crop the window at (crop_left, crop_top) of size (width, height).
struct ImageResizeSpec {
  int resized_width = 0, resized_height = 0;
  int crop_left = 0, crop_top = 0;
  int width = 0, height = 0;
};
ImageResizeSpec ComputeResizeSpec(int in_width, int in_height, int out_width, int out_height,
                                  ResizeMode mode);
// MonST3R/DUSt3R `load_images(size=512)`: long side to `long_side` (each side round(side*512/max)),
// then centre-crop each side to a multiple of 16 (halfw = ((2*cx)//16)*8). 1600x900 -> 512x288.
ImageResizeSpec ComputeMonst3rResizeSpec(int in_width, int in_height, int long_side = 512);
// Camera after applying a resize spec (kIntegerIndex intrinsics unless stated).
PinholeCamera ApplyResizeSpec(const PinholeCamera& camera, const ImageResizeSpec& spec,
                              PixelConvention convention = PixelConvention::kIntegerIndex);

std::string ToString(ResizeMode mode);
// Parses "resize" or "center-crop"; throws InputError otherwise.
ResizeMode ParseResizeMode(const std::string& text);

}  // namespace geodrive
