#include "geometry/camera.h"

#include <cmath>

#include "geometry/util/status.h"

namespace geodrive {

PinholeCamera::PinholeCamera(double fx_in, double fy_in, double cx_in, double cy_in, int w, int h)
    : fx(fx_in), fy(fy_in), cx(cx_in), cy(cy_in), width(w), height(h) {}

PinholeCamera PinholeCamera::FromK(const Eigen::Matrix3d& K, int width, int height) {
  GEODRIVE_CHECK_INPUT(K.allFinite(), "intrinsic matrix has non-finite values");
  GEODRIVE_CHECK_INPUT(K(1, 0) == 0 && K(2, 0) == 0 && K(2, 1) == 0 && K(2, 2) == 1,
                       "intrinsic matrix is not of the form [[fx,s,cx],[0,fy,cy],[0,0,1]]");
  return PinholeCamera(K(0, 0), K(1, 1), K(0, 2), K(1, 2), width, height);
}

Eigen::Matrix3d PinholeCamera::K() const {
  Eigen::Matrix3d k;
  k << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return k;
}

bool PinholeCamera::IsValid() const {
  return std::isfinite(fx) && std::isfinite(fy) && std::isfinite(cx) && std::isfinite(cy) &&
         fx > 0 && fy > 0 && width > 0 && height > 0 && width <= 16384 && height <= 16384;
}

void PinholeCamera::Check(const std::string& what) const {
  GEODRIVE_CHECK_INPUT(std::isfinite(fx) && std::isfinite(fy) && fx > 0 && fy > 0, what,
                       ": focal length must be positive and finite (fx=", fx, ", fy=", fy, ")");
  GEODRIVE_CHECK_INPUT(std::isfinite(cx) && std::isfinite(cy), what,
                       ": principal point is not finite");
  GEODRIVE_CHECK_INPUT(width > 0 && height > 0 && width <= 16384 && height <= 16384, what,
                       ": image size ", width, "x", height, " outside 1..16384");
}

Eigen::Vector2d PinholeCamera::Project(const Eigen::Vector3d& p, PixelConvention convention) const {
  const double offset = convention == PixelConvention::kPixelCenter ? 0.5 : 0.0;
  return Eigen::Vector2d(fx * p.x() / p.z() + cx + offset, fy * p.y() / p.z() + cy + offset);
}

Eigen::Vector3d PinholeCamera::Unproject(const Eigen::Vector2d& pixel, double depth,
                                         PixelConvention convention) const {
  const double offset = convention == PixelConvention::kPixelCenter ? 0.5 : 0.0;
  return Eigen::Vector3d((pixel.x() - offset - cx) / fx * depth,
                         (pixel.y() - offset - cy) / fy * depth, depth);
}

bool PinholeCamera::InImage(const Eigen::Vector2d& pixel) const {
  return pixel.x() >= -0.5 && pixel.y() >= -0.5 && pixel.x() < width - 0.5 &&
         pixel.y() < height - 0.5;
}

PinholeCamera ResizeCamera(const PinholeCamera& c, int new_width, int new_height,
                           PixelConvention convention) {
  GEODRIVE_CHECK_INPUT(c.width > 0 && c.height > 0 && new_width > 0 && new_height > 0,
                       "ResizeCamera: sizes must be positive");
  const double sx = static_cast<double>(new_width) / c.width;
  const double sy = static_cast<double>(new_height) / c.height;
  PinholeCamera out = c;
  out.fx = c.fx * sx;
  out.fy = c.fy * sy;
  if (convention == PixelConvention::kIntegerIndex) {
    out.cx = (c.cx + 0.5) * sx - 0.5;
    out.cy = (c.cy + 0.5) * sy - 0.5;
  } else {
    out.cx = c.cx * sx;
    out.cy = c.cy * sy;
  }
  out.width = new_width;
  out.height = new_height;
  return out;
}

PinholeCamera CropCamera(const PinholeCamera& c, int left, int top, int width, int height) {
  GEODRIVE_CHECK_INPUT(width > 0 && height > 0, "CropCamera: crop size must be positive");
  PinholeCamera out = c;
  out.cx = c.cx - left;
  out.cy = c.cy - top;
  out.width = width;
  out.height = height;
  return out;
}

ImageResizeSpec ComputeResizeSpec(int in_width, int in_height, int out_width, int out_height,
                                  ResizeMode mode) {
  GEODRIVE_CHECK_INPUT(in_width > 0 && in_height > 0 && out_width > 0 && out_height > 0,
                       "resize: sizes must be positive (", in_width, "x", in_height, " -> ",
                       out_width, "x", out_height, ")");
  ImageResizeSpec spec;
  spec.width = out_width;
  spec.height = out_height;
  if (mode == ResizeMode::kResize) {
    spec.resized_width = out_width;
    spec.resized_height = out_height;
    return spec;
  }
  const double s = std::max(static_cast<double>(out_width) / in_width,
                            static_cast<double>(out_height) / in_height);
  spec.resized_width = std::max(out_width, static_cast<int>(std::lround(in_width * s)));
  spec.resized_height = std::max(out_height, static_cast<int>(std::lround(in_height * s)));
  spec.crop_left = (spec.resized_width - out_width) / 2;
  spec.crop_top = (spec.resized_height - out_height) / 2;
  return spec;
}

ImageResizeSpec ComputeMonst3rResizeSpec(int in_width, int in_height, int long_side) {
  GEODRIVE_CHECK_INPUT(in_width > 0 && in_height > 0 && long_side > 0,
                       "MonST3R resize: sizes must be positive");
  const double s = static_cast<double>(long_side) / std::max(in_width, in_height);
  ImageResizeSpec spec;
  // Python's round() on .5 is banker's rounding; image sizes here never hit exact halves in practice
  // (nuScenes 1600x900 -> 512x288 exactly); std::nearbyint uses the same round-half-even rule.
  spec.resized_width = static_cast<int>(std::nearbyint(in_width * s));
  spec.resized_height = static_cast<int>(std::nearbyint(in_height * s));
  const int cx = spec.resized_width / 2, cy = spec.resized_height / 2;
  int halfw = ((2 * cx) / 16) * 8;
  int halfh = ((2 * cy) / 16) * 8;
  if (spec.resized_width == spec.resized_height) halfh = 3 * halfw / 4;  // square -> 4:3
  spec.crop_left = cx - halfw;
  spec.crop_top = cy - halfh;
  spec.width = 2 * halfw;
  spec.height = 2 * halfh;
  return spec;
}

PinholeCamera ApplyResizeSpec(const PinholeCamera& camera, const ImageResizeSpec& spec,
                              PixelConvention convention) {
  const PinholeCamera resized =
      ResizeCamera(camera, spec.resized_width, spec.resized_height, convention);
  return CropCamera(resized, spec.crop_left, spec.crop_top, spec.width, spec.height);
}

std::string ToString(ResizeMode mode) {
  return mode == ResizeMode::kResize ? "resize" : "center-crop";
}

ResizeMode ParseResizeMode(const std::string& text) {
  if (text == "resize") return ResizeMode::kResize;
  if (text == "center-crop" || text == "center") return ResizeMode::kCenterCrop;
  throw InputError("unknown resize mode '" + text + "' (expected resize or center-crop)");
}

}  // namespace geodrive
