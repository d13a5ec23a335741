#include "render/presets.h"

#include <limits>
#include <opencv2/imgproc.hpp>

#include "geometry/util/status.h"

namespace geodrive {

std::string ToString(RenderPreset preset) {
  switch (preset) {
    case RenderPreset::kPaper:
      return "paper";
    case RenderPreset::kGeodriveCompat:
      return "geodrive-compat";
    case RenderPreset::kFootprint:
      return "footprint";
  }
  return "paper";
}

RenderPreset ParseRenderPreset(const std::string& text) {
  if (text == "paper") return RenderPreset::kPaper;
  if (text == "geodrive-compat") return RenderPreset::kGeodriveCompat;
  if (text == "footprint") return RenderPreset::kFootprint;
  ThrowInputError("render preset", "'", text,
                  "' is not one of paper, geodrive-compat, footprint");
}

RenderOptions PresetRenderOptions(RenderPreset preset) {
  RenderOptions o;
  if (preset == RenderPreset::kPaper || preset == RenderPreset::kFootprint) {
    o.mode = RenderMode::kZBuffer;
    o.width = 720;
    o.height = 480;
    o.near = 0.1;
    o.far = 100.0;
    o.radius_px = 0;
    if (preset == RenderPreset::kFootprint) {
      o.splat_size = SplatSize::kFootprint;
      o.max_footprint_magnification = 8.0;
    }
    return o;
  }
  o.mode = RenderMode::kSoft;
  o.width = 512;
  o.height = 288;
  o.near = 0.0;
  o.far = std::numeric_limits<double>::infinity();
  o.radius_ndc = 0.01;
  o.points_per_pixel = 10;
  o.pixel_convention = PixelConvention::kPixelCenter;
  o.output_float_rgb = true;
  return o;
}

int PresetUpsampleFactor(RenderPreset preset) {
  return preset == RenderPreset::kGeodriveCompat ? 2 : 1;
}

std::vector<cv::Mat> FinalFrames(const RenderResult& result,
                                 RenderPreset preset,
                                 const cv::Mat& real_frame0_rgb) {
  const int factor = PresetUpsampleFactor(preset);
  std::vector<cv::Mat> out;
  for (const RenderedFrame& frame : result.frames) {
    if (factor == 1) {
      out.push_back(frame.rgb);
      continue;
    }
    cv::Mat src;
    if (!frame.rgb_float.empty()) {
      src = frame.rgb_float;
    } else {
      frame.rgb.convertTo(src, CV_32FC3, 1.0 / 255);
    }
    cv::Mat up, u8;
    cv::resize(src, up, cv::Size(src.cols * factor, src.rows * factor), 0, 0,
               cv::INTER_LINEAR);
    up.convertTo(u8, CV_8UC3, 255.0);  // saturating round
    out.push_back(u8);
  }
  if (!real_frame0_rgb.empty() && !out.empty()) {
    GEODRIVE_CHECK_INPUT(real_frame0_rgb.type() == CV_8UC3,
                         "render: the real frame 0 must be RGB");
    cv::Mat real;
    cv::resize(real_frame0_rgb, real, out[0].size(), 0, 0, cv::INTER_LINEAR);
    out[0] = real;
  }
  return out;
}

}  // namespace geodrive
