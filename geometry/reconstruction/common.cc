#include "geometry/reconstruction/common.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <filesystem>

#include "geometry/util/status.h"

namespace geodrive {
namespace reconstruction {
namespace {

namespace fs = std::filesystem;

std::string ShapeText(const std::vector<int64_t>& shape) {
  std::string s = "(";
  for (size_t i = 0; i < shape.size(); ++i)
    s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + (shape.size() == 1 ? ",)" : ")");
}

// Any numeric array as doubles (float64 kept exact).
std::vector<double> AsDoubles(const NpyArray& array) {
  std::vector<double> out(static_cast<size_t>(array.NumElements()));
  if (array.dtype == NpyDtype::kFloat64) {
    std::copy(array.Data<double>(), array.Data<double>() + out.size(),
              out.begin());
  } else {
    const NpyArray f = ConvertNpyToFloat32(array);
    std::copy(f.Data<float>(), f.Data<float>() + out.size(), out.begin());
  }
  return out;
}

}  // namespace

std::string ToString(ConfidenceScale scale) {
  switch (scale) {
    case ConfidenceScale::kUnit:
      return "unit";
    case ConfidenceScale::kOnePlus:
      return "1+exp";
    case ConfidenceScale::kLog:
      return "log";
    case ConfidenceScale::kLogit:
      return "logit";
  }
  return "?";
}

ConfidenceScale ParseConfidenceScale(const std::string& text,
                                     const std::string& what) {
  for (ConfidenceScale s : {ConfidenceScale::kUnit, ConfidenceScale::kOnePlus,
                            ConfidenceScale::kLog, ConfidenceScale::kLogit}) {
    if (text == ToString(s)) return s;
  }
  ThrowInputError(what, "unknown confidence scale '", text,
                  "' (expected unit, 1+exp, log or logit)");
}

std::optional<NpyArray> ReadArray(const NpzReader& npz,
                                  const std::string& key,
                                  const ReconstructionReadOptions& options,
                                  bool required) {
  if (!npz.Has(key)) {
    if (!required) return std::nullopt;
    std::string keys;
    for (const std::string& k : npz.Keys())
      keys += (keys.empty() ? "" : ", ") + k;
    ThrowInputError(npz.path(), "no array '", key,
                    "' (the archive has: ", keys.empty() ? "nothing" : keys,
                    ")");
  }
  NpyReadOptions ro;
  ro.max_bytes = options.max_bytes;
  return npz.Read(key, ro);
}

std::vector<cv::Mat> FloatMaps(NpyArray array,
                               const std::string& what,
                               bool depth) {
  const std::vector<int64_t> s = array.shape;  // array is moved below
  GEODRIVE_CHECK_INPUT(
      (s.size() == 3 || (s.size() == 4 && s[3] == 1)) && s[0] >= 1 &&
          s[1] >= 1 && s[2] >= 1 && s[1] <= 16384 && s[2] <= 16384,
      what, ": shape ", ShapeText(s), ", expected (N, H, W) or (N, H, W, 1)");
  const bool half = array.dtype == NpyDtype::kFloat16;
  const NpyArray f = ConvertNpyToFloat32(std::move(array));
  const int n = static_cast<int>(s[0]), h = static_cast<int>(s[1]),
            w = static_cast<int>(s[2]);
  std::vector<cv::Mat> maps(n);
  const float* data = f.Data<float>();
  for (int i = 0; i < n; ++i) {
    maps[i] = cv::Mat(h, w, CV_32FC1);
    std::copy(data + static_cast<size_t>(i) * h * w,
              data + static_cast<size_t>(i + 1) * h * w, maps[i].ptr<float>());
    if (!depth) continue;
    int64_t overflow = 0, finite = 0;
    for (int r = 0; r < h; ++r) {
      const float* p = maps[i].ptr<float>(r);
      for (int c = 0; c < w; ++c) {
        if (std::isinf(p[c]) && p[c] > 0) ++overflow;
        if (std::isfinite(p[c])) ++finite;
      }
    }
    GEODRIVE_CHECK_INPUT(overflow == 0, what, ": frame ", i, " has ", overflow,
                         " infinite depths",
                         half ? " (float16 overflow: depths above 65504)" : "");
    GEODRIVE_CHECK_INPUT(finite > 0, what, ": frame ", i,
                         " has no finite depth");
  }
  return maps;
}

cv::Mat FloatMapFromNpy(const std::string& path,
                        bool depth,
                        const ReconstructionReadOptions& options) {
  NpyReadOptions ro;
  ro.max_bytes = options.max_bytes;
  NpyArray a = ReadNpy(path, ro);
  if (a.shape.size() == 2 || (a.shape.size() == 3 && a.shape[2] == 1))
    a.shape.insert(a.shape.begin(), 1);
  else
    ThrowInputError(path, "shape ", ShapeText(a.shape),
                    ", expected (H, W) or (H, W, 1)");
  return FloatMaps(std::move(a), path, depth).front();
}

cv::Mat ConfidenceToUnit(const cv::Mat& map, ConfidenceScale scale) {
  cv::Mat out(map.size(), CV_32FC1);
  for (int r = 0; r < map.rows; ++r) {
    const float* p = map.ptr<float>(r);
    float* q = out.ptr<float>(r);
    for (int c = 0; c < map.cols; ++c) {
      const double v = p[c];
      double u = 0;
      if (std::isnan(v)) {
        u = 0;
      } else {
        switch (scale) {
          case ConfidenceScale::kUnit:
            u = v;
            break;
          case ConfidenceScale::kOnePlus:  // c = 1 + exp(x) >= 1
            u = v <= 1 ? 0 : 1 - 1 / v;
            break;
          case ConfidenceScale::kLog:  // c = exp(v)
            u = 1 - std::exp(-v);
            break;
          case ConfidenceScale::kLogit:
            u = 1 / (1 + std::exp(-v));
            break;
        }
      }
      q[c] = static_cast<float>(std::clamp(u, 0.0, 1.0));
    }
  }
  return out;
}

std::vector<cv::Mat> ConfidenceMaps(const NpyArray& array,
                                    const std::string& what,
                                    ConfidenceScale scale) {
  std::vector<cv::Mat> maps = FloatMaps(array, what, /*depth=*/false);
  for (cv::Mat& m : maps) m = ConfidenceToUnit(m, scale);
  return maps;
}

Rigid3d PoseFromMatrix(const double* m, int rows, const std::string& what) {
  for (int k = 0; k < rows * 4; ++k)
    GEODRIVE_CHECK_INPUT(std::isfinite(m[k]), what, ": pose is not finite");
  if (rows == 4) {
    GEODRIVE_CHECK_INPUT(m[12] == 0 && m[13] == 0 && m[14] == 0 && m[15] == 1,
                         what, ": bottom row is [", m[12], " ", m[13], " ",
                         m[14], " ", m[15], "], expected [0 0 0 1]");
  }
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R(r, c) = m[r * 4 + c];
    t(r) = m[r * 4 + 3];
  }
  const double det = R.determinant();
  GEODRIVE_CHECK_INPUT(det > 0, what, ": rotation has determinant ", det,
                       " (a reflection: OpenGL-flipped axes? poses must be "
                       "OpenCV x right, y down, z forward)");
  const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm();
  GEODRIVE_CHECK_INPUT(err <= 1e-3, what,
                       ": not a rotation (|R^T R - I| = ", err,
                       "; a scaled or sheared matrix?)");
  Eigen::Quaterniond q(R);
  q.normalize();
  return Rigid3d(q, t);
}

std::vector<Rigid3d> Poses(const NpyArray& array,
                           const std::string& what,
                           bool w2c) {
  std::vector<int64_t> s = array.shape;
  if (s.size() == 2) s.insert(s.begin(), 1);
  GEODRIVE_CHECK_INPUT(
      s.size() == 3 && s[0] >= 1 && (s[1] == 3 || s[1] == 4) && s[2] == 4, what,
      ": shape ", ShapeText(array.shape), ", expected (N, 3, 4) or (N, 4, 4)");
  const std::vector<double> data = AsDoubles(array);
  const int rows = static_cast<int>(s[1]);
  std::vector<Rigid3d> poses;
  for (int64_t i = 0; i < s[0]; ++i) {
    double m[16];
    for (int k = 0; k < rows * 4; ++k) m[k] = data[i * rows * 4 + k];
    const Rigid3d p =
        PoseFromMatrix(m, rows, what + " pose " + std::to_string(i));
    poses.push_back(w2c ? p.Inverse() : p);
  }
  return poses;
}

std::vector<PinholeCamera> Cameras(const NpyArray& array,
                                   const std::string& what,
                                   int num_frames,
                                   int width,
                                   int height) {
  const auto& s = array.shape;
  const bool shared = s.size() == 2 && s[0] == 3 && s[1] == 3;
  GEODRIVE_CHECK_INPUT(
      shared || (s.size() == 3 && s[0] == num_frames && s[1] == 3 && s[2] == 3),
      what, ": shape ", ShapeText(s), ", expected (3, 3) or (", num_frames,
      ", 3, 3)");
  const std::vector<double> d = AsDoubles(array);
  std::vector<PinholeCamera> cameras;
  for (int i = 0; i < num_frames; ++i) {
    const double* k = d.data() + (shared ? 0 : 9 * i);
    const std::string w = what + " frame " + std::to_string(i);
    for (int j = 0; j < 9; ++j)
      GEODRIVE_CHECK_INPUT(std::isfinite(k[j]), w, ": K is not finite");
    GEODRIVE_CHECK_INPUT(k[6] == 0 && k[7] == 0 && k[8] == 1, w,
                         ": K's last row is [", k[6], " ", k[7], " ", k[8],
                         "], expected [0 0 1]");
    GEODRIVE_CHECK_INPUT(k[1] == 0 && k[3] == 0, w,
                         ": K has skew or is transposed (K[0][1] = ", k[1],
                         ", K[1][0] = ", k[3], ")");
    GEODRIVE_CHECK_INPUT(k[0] > 0 && k[4] > 0, w, ": focal lengths ", k[0],
                         ", ", k[4], " must be positive");
    GEODRIVE_CHECK_INPUT(
        k[0] > 2 || k[4] > 2, w, ": K looks normalized (fx = ", k[0],
        "); expected pixels of the ", width, "x", height, " grid");
    cameras.emplace_back(k[0], k[4], k[2], k[5], width, height);
  }
  return cameras;
}

std::vector<cv::Mat> Images(const NpyArray& array, const std::string& what) {
  const auto& s = array.shape;
  GEODRIVE_CHECK_INPUT(s.size() == 4 && (s[3] == 3 || s[1] == 3), what,
                       ": shape ", ShapeText(s),
                       ", expected (N, H, W, 3) or (N, 3, H, W)");
  const bool chw = s[3] != 3;
  const int n = static_cast<int>(s[0]);
  const int h = static_cast<int>(chw ? s[2] : s[1]);
  const int w = static_cast<int>(chw ? s[3] : s[2]);
  std::vector<cv::Mat> images(n);
  const bool u8 = array.dtype == NpyDtype::kUint8;
  NpyArray f;
  if (!u8) f = ConvertNpyToFloat32(array);
  const size_t plane = static_cast<size_t>(h) * w;
  for (int i = 0; i < n; ++i) {
    images[i] = cv::Mat(h, w, CV_8UC3);
    for (int r = 0; r < h; ++r) {
      auto* out = images[i].ptr<cv::Vec3b>(r);
      for (int c = 0; c < w; ++c) {
        for (int ch = 0; ch < 3; ++ch) {
          const size_t idx = chw ? (i * 3 + ch) * plane + r * w + c
                                 : ((i * plane) + r * w + c) * 3 + ch;
          if (u8) {
            out[c][ch] = array.bytes[idx];
          } else {
            const float v = f.Data<float>()[idx];
            GEODRIVE_CHECK_INPUT(std::isfinite(v), what,
                                 ": image value is not finite");
            out[c][ch] = static_cast<uint8_t>(
                std::lround(std::clamp(v, 0.f, 1.f) * 255.f));
          }
        }
      }
    }
  }
  return images;
}

void CheckMotionDirection(const std::vector<Rigid3d>& world_from_cam,
                          const std::string& what,
                          const std::string& hint) {
  int moving = 0, backwards = 0;
  for (size_t i = 1; i < world_from_cam.size(); ++i) {
    const Eigen::Vector3d step =
        world_from_cam[i].translation - world_from_cam[i - 1].translation;
    if (step.norm() < 1e-9) continue;
    const Eigen::Vector3d forward =
        world_from_cam[i - 1].rotation * Eigen::Vector3d::UnitZ();
    ++moving;
    if (step.normalized().dot(forward) < -0.7) ++backwards;
  }
  GEODRIVE_CHECK_INPUT(
      moving < 3 || backwards < moving, what,
      ": the camera moves backwards along its optical axis in every one of ",
      moving,
      " steps: these look like world-to-camera poses read as "
      "camera-to-world; ",
      hint);
}

Monst3rFolder Assemble(const std::string& name,
                       const std::string& tool,
                       Arrays a,
                       GridResize resize,
                       const std::string& units) {
  const size_t n = a.depth.size();
  auto count = [&](size_t have, const char* kind) {
    GEODRIVE_CHECK_INPUT(have == 0 || have == n, name, ": ", have, " ", kind,
                         " for ", n, " depth maps");
  };
  count(a.confidence01.size(), "confidence maps");
  count(a.rgb.size(), "images");
  count(a.dynamic_mask.size(), "masks");
  GEODRIVE_CHECK_INPUT(a.cameras.size() == n, name, ": ", a.cameras.size(),
                       " intrinsics for ", n, " depth maps");
  GEODRIVE_CHECK_INPUT(a.world_from_cam.size() == n, name, ": ",
                       a.world_from_cam.size(), " poses for ", n,
                       " depth maps");
  std::vector<Monst3rFrame> frames(n);
  for (size_t i = 0; i < n; ++i) {
    Monst3rFrame& f = frames[i];
    f.depth = a.depth[i];
    f.camera = a.cameras[i];
    f.world_from_cam = a.world_from_cam[i];
    if (!a.confidence01.empty()) f.confidence01 = a.confidence01[i];
    if (!a.rgb.empty()) f.rgb = a.rgb[i];
    if (!a.dynamic_mask.empty()) f.dynamic_mask = a.dynamic_mask[i];
  }
  return Monst3rFolder::FromFrames(name, tool, std::move(frames), resize,
                                   units);
}

std::optional<std::string> FindFile(const std::string& path,
                                    const std::vector<std::string>& suffixes) {
  auto matches = [&](const std::string& file) {
    for (const std::string& s : suffixes) {
      if (file.size() >= s.size() &&
          file.compare(file.size() - s.size(), s.size(), s) == 0)
        return true;
    }
    return false;
  };
  std::error_code ec;
  if (fs::is_regular_file(path, ec))
    return matches(fs::path(path).filename().string())
               ? std::optional<std::string>(path)
               : std::nullopt;
  if (!fs::is_directory(path, ec)) return std::nullopt;
  std::vector<std::string> found;
  for (const auto& e : fs::directory_iterator(path, ec)) {
    if (e.is_regular_file() && matches(e.path().filename().string()))
      found.push_back(e.path().string());
  }
  if (found.empty()) return std::nullopt;
  std::sort(found.begin(), found.end());
  return found.front();
}

bool NpzHasKeys(const std::string& path, const std::vector<std::string>& keys) {
  if (!LooksLikeZip(path)) return false;
  try {
    const NpzReader npz(path);
    for (const std::string& k : keys)
      if (!npz.Has(k)) return false;
    return true;
  } catch (const InputError&) {
    return false;
  }
}

}  // namespace reconstruction
}  // namespace geodrive
