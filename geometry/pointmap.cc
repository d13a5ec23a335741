#include "geometry/pointmap.h"

#include <glog/logging.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "geometry/npy.h"
#include "geometry/util/input_file.h"
#include "geometry/util/status.h"

namespace geodrive {

Pointmap BuildPointmap(const Monst3rFrame& frame,
                       double depth_scale,
                       ConfidenceSource source) {
  GEODRIVE_CHECK_INPUT(std::isfinite(depth_scale) && depth_scale > 0,
                       "depth scale ", depth_scale,
                       " must be positive and finite");
  GEODRIVE_CHECK_INPUT(!frame.depth.empty() && frame.depth.type() == CV_32FC1,
                       "MonST3R frame ", frame.index,
                       ": no float depth map loaded");
  Pointmap pm;
  pm.frame_index = frame.index;
  pm.camera = frame.camera;
  pm.world_from_cam = frame.world_from_cam;
  pm.world_from_cam.translation *= depth_scale;
  const int h = frame.depth.rows, w = frame.depth.cols;
  pm.depth.create(h, w, CV_32FC1);
  pm.points_in_world.create(h, w, CV_32FC3);
  const Eigen::Matrix3f R =
      pm.world_from_cam.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f t = pm.world_from_cam.translation.cast<float>();
  const float fx_inv = static_cast<float>(1.0 / frame.camera.fx);
  const float fy_inv = static_cast<float>(1.0 / frame.camera.fy);
  const float cx = static_cast<float>(frame.camera.cx),
              cy = static_cast<float>(frame.camera.cy);
  const float scale = static_cast<float>(depth_scale);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int v = 0; v < h; ++v) {
    const float* d_in = frame.depth.ptr<float>(v);
    float* d_out = pm.depth.ptr<float>(v);
    auto* p_out = pm.points_in_world.ptr<cv::Vec3f>(v);
    const float y_n = (static_cast<float>(v) - cy) * fy_inv;
    for (int u = 0; u < w; ++u) {
      const float d = d_in[u] * scale;
      d_out[u] = d;
      if (!std::isfinite(d)) {
        p_out[u] = cv::Vec3f(nan, nan, nan);
        continue;
      }
      // Integer-index pixel convention (no +0.5), as MonST3R.
      const Eigen::Vector3f x_cam((static_cast<float>(u) - cx) * fx_inv * d,
                                  y_n * d, d);
      const Eigen::Vector3f x_world = R * x_cam + t;
      p_out[u] = cv::Vec3f(x_world.x(), x_world.y(), x_world.z());
    }
  }
  const cv::Mat& conf = source == ConfidenceSource::kInitConf
                            ? frame.init_log_confidence
                            : frame.log_confidence;
  if (!conf.empty())
    pm.confidence = ConfidenceMapToUnit(conf, ConfidenceEncoding::kLog);
  else if (source != ConfidenceSource::kInitConf)
    pm.confidence = frame.confidence01;  // another tool's, already in [0, 1]
  pm.dynamic_mask = frame.dynamic_mask;
  pm.enlarged_dynamic_mask = frame.enlarged_dynamic_mask;
  pm.rgb = frame.rgb;
  return pm;
}

Pointmap PointmapFromRawPoints(const RawPointmap& raw,
                               const PinholeCamera& camera,
                               const Rigid3d& world_from_cam,
                               int frame_index) {
  GEODRIVE_CHECK_INPUT(raw.points_in_world.type() == CV_32FC3,
                       "raw pointmap of frame ", frame_index,
                       ": expected CV_32FC3 points");
  Pointmap pm;
  pm.frame_index = frame_index;
  pm.camera = camera;
  pm.world_from_cam = world_from_cam;
  pm.points_in_world = raw.points_in_world;
  pm.confidence = raw.confidence01;
  pm.rgb = raw.rgb;
  const Rigid3d cam_from_world = world_from_cam.Inverse();
  const Eigen::Matrix3f R =
      cam_from_world.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f t = cam_from_world.translation.cast<float>();
  pm.depth.create(raw.points_in_world.size(), CV_32FC1);
  for (int v = 0; v < pm.depth.rows; ++v) {
    const auto* p = raw.points_in_world.ptr<cv::Vec3f>(v);
    float* d = pm.depth.ptr<float>(v);
    for (int u = 0; u < pm.depth.cols; ++u) {
      d[u] = R.row(2).dot(Eigen::Vector3f(p[u][0], p[u][1], p[u][2])) + t.z();
    }
  }
  return pm;
}

void PointmapFilterOptions::Check() const {
  GEODRIVE_CHECK_INPUT(std::isfinite(min_confidence) && min_confidence >= 0 &&
                           min_confidence <= 1,
                       "min_confidence ", min_confidence, " must be in [0, 1]");
  GEODRIVE_CHECK_INPUT(std::isfinite(min_depth) && min_depth >= 0, "min_depth ",
                       min_depth, " must be >= 0");
  GEODRIVE_CHECK_INPUT(max_depth > min_depth, "max_depth ", max_depth,
                       " must exceed min_depth ", min_depth);
  GEODRIVE_CHECK_INPUT(stride >= 1 && stride <= 4096, "stride ", stride,
                       " must be in [1, 4096]");
}

void PointmapFilterStats::Add(const PointmapFilterStats& o) {
  total += o.total;
  non_finite += o.non_finite;
  out_of_range += o.out_of_range;
  low_confidence += o.low_confidence;
  masked += o.masked;
  kept += o.kept;
}

std::string PointmapFilterStats::ToString() const {
  std::ostringstream os;
  os << "pixels " << total << ": kept " << kept << ", non-finite " << non_finite
     << ", depth out of range " << out_of_range << ", low confidence "
     << low_confidence << ", masked (static/dynamic) " << masked;
  return os.str();
}

cv::Mat ComputeValidMask(const Pointmap& pm,
                         const PointmapFilterOptions& options,
                         PointmapFilterStats* stats) {
  options.Check();
  const int h = pm.height(), w = pm.width();
  cv::Mat valid(h, w, CV_8UC1, cv::Scalar(0));
  const cv::Mat& mask =
      options.mask_kind == DynamicMaskKind::kEnlarged &&
              !pm.enlarged_dynamic_mask.empty()
          ? pm.enlarged_dynamic_mask
          : (pm.dynamic_mask.empty() ? pm.enlarged_dynamic_mask
                                     : pm.dynamic_mask);
  const bool use_conf = !pm.confidence.empty() && options.min_confidence > 0;
  const float min_conf = static_cast<float>(options.min_confidence);
  const float min_d = static_cast<float>(options.min_depth);
  const float max_d = static_cast<float>(options.max_depth);
  PointmapFilterStats s;
  for (int v = 0; v < h; v += options.stride) {
    const float* d = pm.depth.ptr<float>(v);
    const auto* p = pm.points_in_world.ptr<cv::Vec3f>(v);
    const float* c = use_conf ? pm.confidence.ptr<float>(v) : nullptr;
    const uint8_t* m = mask.empty() ? nullptr : mask.ptr<uint8_t>(v);
    uint8_t* out = valid.ptr<uint8_t>(v);
    for (int u = 0; u < w; u += options.stride) {
      ++s.total;
      if (!std::isfinite(d[u]) || !std::isfinite(p[u][0]) ||
          !std::isfinite(p[u][1]) || !std::isfinite(p[u][2])) {
        ++s.non_finite;
        continue;
      }
      if (d[u] < min_d || d[u] > max_d) {
        ++s.out_of_range;
        continue;
      }
      if (c && !(c[u] >= min_conf)) {
        ++s.low_confidence;
        continue;
      }
      const bool dynamic = m && m[u] > 127;
      if ((options.selection == PixelSelection::kStaticOnly && dynamic) ||
          (options.selection == PixelSelection::kDynamicOnly && !dynamic)) {
        ++s.masked;
        continue;
      }
      ++s.kept;
      out[u] = 255;
    }
  }
  if (stats) *stats = s;
  return valid;
}

PointCloud ExtractPoints(const Pointmap& pm,
                         const cv::Mat& valid_mask,
                         std::vector<PointProvenance>* provenance,
                         std::vector<float>* depths) {
  CHECK_EQ(valid_mask.type(), CV_8UC1);
  const int64_t n = cv::countNonZero(valid_mask);
  PointCloud cloud;
  cloud.positions.reserve(n);
  const bool has_rgb = !pm.rgb.empty();
  const bool has_conf = !pm.confidence.empty();
  if (has_rgb) cloud.colors.reserve(n);
  if (has_conf) cloud.confidence.reserve(n);
  if (provenance) {
    provenance->clear();
    provenance->reserve(n);
  }
  if (depths) {
    depths->clear();
    depths->reserve(n);
  }
  for (int v = 0; v < valid_mask.rows; ++v) {
    const uint8_t* m = valid_mask.ptr<uint8_t>(v);
    const auto* p = pm.points_in_world.ptr<cv::Vec3f>(v);
    for (int u = 0; u < valid_mask.cols; ++u) {
      if (!m[u]) continue;
      cloud.positions.emplace_back(p[u][0], p[u][1], p[u][2]);
      if (has_rgb) {
        const auto& c = pm.rgb.at<cv::Vec3b>(v, u);
        cloud.colors.emplace_back(c[0], c[1], c[2]);
      }
      if (has_conf) cloud.confidence.push_back(pm.confidence.at<float>(v, u));
      if (provenance) {
        provenance->push_back(
            {pm.frame_index, static_cast<int16_t>(u), static_cast<int16_t>(v)});
      }
      if (depths) depths->push_back(pm.depth.at<float>(v, u));
    }
  }
  return cloud;
}

PinholeCamera ReadIntrinsicsFile(const std::string& path,
                                 int width,
                                 int height) {
  InputFileStream in(path);
  std::vector<double> values;
  std::string token;
  while (in >> token) {
    try {
      size_t used = 0;
      values.push_back(std::stod(token, &used));
      if (used != token.size()) throw std::invalid_argument(token);
    } catch (const std::logic_error&) {
      ThrowInputError(path, "'", token, "' is not a number");
    }
  }
  if (values.size() < 9 || values.size() % 9 != 0) {
    ThrowInputError(path, values.size(),
                    " numbers (expected a 3x3 K: 9 per frame)");
  }
  Eigen::Matrix3d K;
  for (int i = 0; i < 9; ++i) K(i / 3, i % 3) = values[i];
  GEODRIVE_CHECK_INPUT(K.allFinite(), path, ": non-finite value in K");
  GEODRIVE_CHECK_INPUT(K(1, 0) == 0 && K(2, 0) == 0 && K(2, 1) == 0 &&
                           K(2, 2) == 1 && K(0, 1) == 0,
                       path, ": not a pinhole K [[fx,0,cx],[0,fy,cy],[0,0,1]]");
  const PinholeCamera camera = PinholeCamera::FromK(K, width, height);
  camera.Check(path);
  return camera;
}

cv::Mat ReadDepthNpy(const std::string& path) {
  const NpyArray a = ReadNpyAsFloat32(path);
  std::vector<int64_t> shape = a.shape;
  while (shape.size() > 2 && shape.front() == 1) shape.erase(shape.begin());
  while (shape.size() > 2 && shape.back() == 1) shape.pop_back();
  GEODRIVE_CHECK_INPUT(shape.size() == 2 && shape[0] > 0 && shape[1] > 0 &&
                           shape[0] <= 16384 && shape[1] <= 16384,
                       path, ": expected a (H, W) depth array");
  cv::Mat depth(static_cast<int>(shape[0]), static_cast<int>(shape[1]), CV_32F);
  std::memcpy(depth.data, a.Data<float>(), depth.total() * sizeof(float));
  return depth;
}

PointCloud CloudFromDepth(const cv::Mat& depth,
                          const cv::Mat& rgb,
                          const PinholeCamera& camera,
                          const Rigid3d& world_from_cam) {
  PointCloud cloud;
  cloud.Reserve(depth.total());
  for (int j = 0; j < depth.rows; ++j) {
    for (int i = 0; i < depth.cols; ++i) {
      const float z = depth.at<float>(j, i);
      if (!(z > 0) || !std::isfinite(z)) continue;
      const Eigen::Vector3d p =
          world_from_cam * camera.Unproject(Eigen::Vector2d(i, j), z,
                                            PixelConvention::kIntegerIndex);
      cloud.positions.push_back(p.cast<float>());
      const cv::Vec3b c = rgb.at<cv::Vec3b>(j, i);
      cloud.colors.push_back(Color3u8(c[0], c[1], c[2]));
    }
  }
  return cloud;
}

}  // namespace geodrive
