// MoGe / MoGe-2 (microsoft/MoGe) `infer.py --maps` output, one folder per
// image:
//   depth.exr   z-depth, one float channel (cv2.imwrite: "Y"); inf where the
//               model masks the pixel out
//   points.exr  the camera-frame points, written with cvtColor(points,
//               RGB2BGR), so the file's R, G, B channels hold x, y, z
//               (optional: sharper intrinsics than fov.json)
//   mask.png    0/255, 255 = valid (optional)
//   fov.json    {"fov_x", "fov_y"} in degrees, rounded to 2 decimals
//   image.jpg   the input image (optional)
// OpenCV axes (the maps; only the .ply/.glb exports flip to OpenGL). A single
// image: one frame at the identity pose; the trajectory comes from the clip
// (build-dataset) or --trajectory (render). Intrinsics: fitted to points.exr
// by least squares (u = fx x/z + cx, v = fy y/z + cy over valid pixels),
// else from the field of view with the principal point at the image centre
// (utils3d's normalized intrinsics: cx = W/2 - 0.5 in integer-index pixels).
// Depth as read: metres for MoGe-2, up to scale for MoGe-1 (the folder does
// not say which), so the LiDAR fit sets the scale.

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "geometry/exr.h"
#include "geometry/image_io.h"
#include "geometry/reconstruction/common.h"
#include "geometry/util/input_file.h"
#include "geometry/util/json_depth.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace reconstruction {
namespace {

namespace fs = std::filesystem;

std::string Pick(const std::vector<std::string>& have,
                 const std::vector<std::string>& wanted) {
  for (const std::string& w : wanted)
    for (const std::string& h : have)
      if (h == w) return h;
  return have.empty() ? "" : have.front();
}

// fx, cx (axis 0) and fy, cy (axis 1) fitted to the points: u = f * x/z + c.
bool FitIntrinsics(const cv::Mat& points,
                   const cv::Mat& valid,
                   double* fx,
                   double* fy,
                   double* cx,
                   double* cy) {
  double s[2][5] = {};  // n, sum a, sum a^2, sum u, sum a*u
  for (int v = 0; v < points.rows; ++v) {
    const auto* p = points.ptr<cv::Vec3f>(v);
    for (int u = 0; u < points.cols; ++u) {
      if (!valid.at<uint8_t>(v, u) || !(p[u][2] > 0) ||
          !std::isfinite(p[u][0]) || !std::isfinite(p[u][1]))
        continue;
      const double a[2] = {p[u][0] / p[u][2], p[u][1] / p[u][2]};
      const double b[2] = {double(u), double(v)};
      for (int k = 0; k < 2; ++k) {
        s[k][0] += 1, s[k][1] += a[k], s[k][2] += a[k] * a[k];
        s[k][3] += b[k], s[k][4] += a[k] * b[k];
      }
    }
  }
  double f[2], c[2];
  for (int k = 0; k < 2; ++k) {
    const double det = s[k][0] * s[k][2] - s[k][1] * s[k][1];
    if (s[k][0] < 100 || !(std::abs(det) > 1e-12)) return false;
    f[k] = (s[k][0] * s[k][4] - s[k][1] * s[k][3]) / det;
    c[k] = (s[k][3] - f[k] * s[k][1]) / s[k][0];
  }
  *fx = f[0], *fy = f[1], *cx = c[0], *cy = c[1];
  return *fx > 0 && *fy > 0;
}

class MogeReader : public ReconstructionReader {
 public:
  ReconstructionFormat format() const override {
    return ReconstructionFormat::kMoge;
  }
  std::string ToolName() const override { return "MoGe"; }
  ReconstructionConventions Conventions() const override {
    return {
        "single image: identity (camera 0); the trajectory comes from "
        "the clip or --trajectory",
        "mask.png: 1 inside, 0 outside (no graded confidence)",
        "fitted to points.exr (u = fx x/z + cx), else fov.json with the "
        "principal point at the centre; the input image's grid",
        "metres for MoGe-2, up to scale for MoGe-1 (the LiDAR fit sets "
        "it)"};
  }
  std::optional<std::string> Locate(const std::string& path) const override {
    std::error_code ec;
    if (fs::is_regular_file(path + "/depth.exr", ec) &&
        (fs::is_regular_file(path + "/fov.json", ec) ||
         fs::is_regular_file(path + "/points.exr", ec)))
      return path;
    return std::nullopt;
  }
  Monst3rFolder Read(const std::string& path,
                     const ReconstructionReadOptions&) const override {
    GEODRIVE_CHECK_INPUT(Locate(path), path,
                         ": not a MoGe --maps folder (needs depth.exr and "
                         "fov.json or points.exr)");
    const std::string depth_path = path + "/depth.exr";
    const std::vector<std::string> ch = ExrChannels(depth_path);
    cv::Mat depth = ReadExr(depth_path, {Pick(ch, {"Y", "Z", "R", "depth"})});
    const int w = depth.cols, h = depth.rows;
    cv::Mat valid(h, w, CV_8UC1, cv::Scalar(255));
    std::error_code ec;
    if (fs::is_regular_file(path + "/mask.png", ec)) {
      const cv::Mat mask = ReadImageGray(path + "/mask.png");
      GEODRIVE_CHECK_INPUT(mask.cols == w && mask.rows == h, path + "/mask.png",
                           ": ", mask.cols, "x", mask.rows,
                           " but depth.exr is ", w, "x", h);
      valid = mask > 127;
    }
    int64_t finite = 0;
    for (int v = 0; v < h; ++v) {
      float* d = depth.ptr<float>(v);
      for (int u = 0; u < w; ++u) {
        if (!valid.at<uint8_t>(v, u) || !std::isfinite(d[u]) || d[u] <= 0)
          d[u] = NAN;  // no depth: outside the mask, sky (inf)
        else
          ++finite;
      }
    }
    GEODRIVE_CHECK_INPUT(finite > 0, depth_path, ": no valid depth");
    PinholeCamera camera;
    bool fitted = false;
    if (fs::is_regular_file(path + "/points.exr", ec)) {
      const cv::Mat points = ReadExr(path + "/points.exr", {"R", "G", "B"});
      GEODRIVE_CHECK_INPUT(points.cols == w && points.rows == h,
                           path + "/points.exr", ": ", points.cols, "x",
                           points.rows, " but depth.exr is ", w, "x", h);
      double fx, fy, cx, cy;
      fitted = FitIntrinsics(points, valid, &fx, &fy, &cx, &cy);
      if (fitted) camera = PinholeCamera(fx, fy, cx, cy, w, h);
    }
    if (!fitted) {
      const std::string fov_path = path + "/fov.json";
      nlohmann::json j;
      InputFileStream in(fov_path);
      try {
        j = internal::ParseJson(in, fov_path);
      } catch (const std::exception& e) {
        ThrowInputError(fov_path, "not readable JSON: ", e.what());
      }
      GEODRIVE_CHECK_INPUT(j.is_object() && j.contains("fov_x") &&
                               j["fov_x"].is_number() && j.contains("fov_y") &&
                               j["fov_y"].is_number(),
                           fov_path, ": needs numbers fov_x and fov_y (deg)");
      const double fov_x = j["fov_x"].get<double>() * M_PI / 180;
      const double fov_y = j["fov_y"].get<double>() * M_PI / 180;
      GEODRIVE_CHECK_INPUT(
          fov_x > 0 && fov_x < M_PI && fov_y > 0 && fov_y < M_PI, fov_path,
          ": fields of view must be in (0, 180)");
      camera = PinholeCamera(0.5 * w / std::tan(fov_x / 2),
                             0.5 * h / std::tan(fov_y / 2), 0.5 * w - 0.5,
                             0.5 * h - 0.5, w, h);
    }
    Arrays a;
    a.depth.push_back(depth);
    a.cameras.push_back(camera);
    a.world_from_cam.push_back(Rigid3d());
    for (const char* name : {"/image.jpg", "/image.png"}) {
      if (fs::is_regular_file(path + name, ec)) {
        cv::Mat rgb = ReadImageRgb(path + name);
        GEODRIVE_CHECK_INPUT(rgb.cols == w && rgb.rows == h, path + name, ": ",
                             rgb.cols, "x", rgb.rows, " but depth.exr is ", w,
                             "x", h);
        a.rgb.push_back(rgb);
        break;
      }
    }
    return Assemble(path, ToolName(), std::move(a), GridResize::kStretch, "");
  }
};

}  // namespace

std::unique_ptr<ReconstructionReader> CreateMogeReader() {
  return std::make_unique<MogeReader>();
}

}  // namespace reconstruction
}  // namespace geodrive
