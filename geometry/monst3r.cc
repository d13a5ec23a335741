#include "geometry/monst3r.h"

#include <glog/logging.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <regex>
#include <sstream>

#include "geometry/image_io.h"
#include "geometry/npy.h"
#include "geometry/trajectory_io.h"
#include "geometry/util/input_file.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;

// Per-kind map index -> file name, from the directory scan.
struct FileSet {
  std::map<int, std::string> files;
  bool empty() const { return files.empty(); }
};

std::string JoinPath(const std::string& dir, const std::string& name) {
  return (fs::path(dir) / name).string();
}

// Checks that `set` covers exactly 0..n-1; `pattern` names the files in errors.
void CheckCoverage(const std::string& dir,
                   const FileSet& set,
                   int n,
                   const std::string& pattern,
                   const std::string& counted_by) {
  for (int i = 0; i < n; ++i) {
    if (!set.files.count(i)) {
      std::string name = pattern;
      const size_t pos = name.find("{i}");
      name.replace(pos, 3, std::to_string(i));
      ThrowInputError(JoinPath(dir, name), "missing (", set.files.size(), " ",
                      pattern.substr(0, pattern.find("{i}")), "* files for ", n,
                      " frames in ", counted_by, ")");
    }
  }
  if (static_cast<int>(set.files.size()) != n) {
    const auto& extra = *set.files.rbegin();
    ThrowInputError(JoinPath(dir, extra.second), "frame index ", extra.first,
                    " beyond the clip: mismatched frame counts (",
                    set.files.size(), " files vs ", n, " frames in ",
                    counted_by, ")");
  }
}

cv::Mat NpyToMat(const NpyArray& array,
                 int channels_expected,
                 const std::string& path) {
  const auto& s = array.shape;
  int h = 0, w = 0, c = 1;
  if (s.size() == 2) {
    h = static_cast<int>(s[0]);
    w = static_cast<int>(s[1]);
  } else if (s.size() == 3) {
    h = static_cast<int>(s[0]);
    w = static_cast<int>(s[1]);
    c = static_cast<int>(s[2]);
  } else {
    ThrowInputError(path, "expected a 2-D or 3-D array, got ", s.size(),
                    " dimensions");
  }
  if (channels_expected > 0) {
    GEODRIVE_CHECK_INPUT(c == channels_expected, path, ": expected ",
                         channels_expected, " channel(s), got shape with ", c);
  }
  GEODRIVE_CHECK_INPUT(h > 0 && w > 0 && c >= 1 && c <= 4, path,
                       ": unsupported shape ", h, "x", w, "x", c);
  cv::Mat mat(h, w, CV_32FC(c));
  std::memcpy(mat.data, array.Data<float>(),
              sizeof(float) * static_cast<size_t>(h) * w * c);
  return mat;
}

cv::Mat ReadFloatMap(const std::string& path, int channels) {
  return NpyToMat(ReadNpyAsFloat32(path), channels, path);
}

// Reads an (H, W[, C]) map after checking, from the header alone, that its
// height and width are `height` x `width`: a map of the wrong (possibly huge)
// shape is refused before anything is allocated for it.
cv::Mat ReadFloatMapOfShape(const std::string& path,
                            int channels,
                            int width,
                            int height,
                            const std::string& reference) {
  const NpyHeader header = ReadNpyHeader(path);
  if (header.shape.size() >= 2 &&
      (header.shape[0] != height || header.shape[1] != width)) {
    ThrowInputError(path, "shape ", header.shape[0], "x", header.shape[1],
                    " (HxW) differs from ", reference, " ", height, "x", width);
  }
  return ReadFloatMap(path, channels);
}

void CheckShape(const cv::Mat& m,
                int width,
                int height,
                const std::string& path,
                const std::string& reference) {
  if (m.cols != width || m.rows != height) {
    ThrowInputError(path, "shape ", m.rows, "x", m.cols, " (HxW) differs from ",
                    reference, " ", height, "x", width);
  }
}

cv::Mat ReadMask(const std::string& path,
                 int width,
                 int height,
                 const std::string& reference) {
  cv::Mat mask = ReadImageGray(path);
  CheckShape(mask, width, height, path, reference);
  return mask;
}

}  // namespace

float ConfidenceToUnit(float value, ConfidenceEncoding encoding) {
  if (std::isnan(value)) return 0.f;
  switch (encoding) {
    case ConfidenceEncoding::kLog:
      if (value <= 0.f) return 0.f;  // raw <= 1 (and -inf): no confidence
      return static_cast<float>(-std::expm1(-static_cast<double>(value)));
    case ConfidenceEncoding::kRaw:
      if (value <= 1.f) return 0.f;
      return 1.f - 1.f / value;
    case ConfidenceEncoding::kUnit:
      return std::clamp(value, 0.f, 1.f);
  }
  return 0.f;
}

cv::Mat ConfidenceMapToUnit(const cv::Mat& confidence,
                            ConfidenceEncoding encoding) {
  CHECK_EQ(confidence.type(), CV_32FC1);
  cv::Mat out(confidence.size(), CV_32FC1);
  for (int r = 0; r < confidence.rows; ++r) {
    const float* in = confidence.ptr<float>(r);
    float* o = out.ptr<float>(r);
    for (int c = 0; c < confidence.cols; ++c)
      o[c] = ConfidenceToUnit(in[c], encoding);
  }
  return out;
}

std::string ToString(GridResize resize) {
  switch (resize) {
    case GridResize::kMonst3r:
      return "monst3r-512";
    case GridResize::kVggt:
      return "vggt-518";
    case GridResize::kStretch:
      return "stretch";
    case GridResize::kCenterCrop:
      return "center-crop";
  }
  return "?";
}

ImageResizeSpec ComputeGridResizeSpec(GridResize rule,
                                      int in_width,
                                      int in_height) {
  switch (rule) {
    case GridResize::kMonst3r:
      return ComputeMonst3rResizeSpec(in_width, in_height, 512);
    case GridResize::kVggt: {
      // vggt/utils/load_fn.py, mode "crop": new_width = 518, new_height =
      // round(height * (518 / width) / 14) * 14, then a centre crop of the
      // height to 518 (start_y = (new_height - 518) // 2).
      ImageResizeSpec s;
      s.resized_width = 518;
      s.resized_height = static_cast<int>(
          std::lround(in_height * (518.0 / in_width) / 14.0) * 14);
      s.width = 518;
      s.height = std::min(s.resized_height, 518);
      s.crop_top = (s.resized_height - s.height) / 2;
      return s;
    }
    case GridResize::kStretch:
    case GridResize::kCenterCrop:
      break;
  }
  // kStretch and kCenterCrop need the grid: see SourceToGrid.
  return ImageResizeSpec{};
}

namespace {
// Frame `stored` of an in-memory reconstruction, with what `options` asks.
Monst3rFrame LoadMemoryFrame(const Monst3rFrame& stored,
                             const Monst3rLoadOptions& options) {
  Monst3rFrame f;
  f.index = stored.index;
  f.camera = stored.camera;
  f.world_from_cam = stored.world_from_cam;
  f.depth = stored.depth;  // shared, read-only by convention (cv::Mat refs)
  if (options.rgb) f.rgb = stored.rgb;
  if (options.confidence) f.confidence01 = stored.confidence01;
  if (options.dynamic_masks) f.dynamic_mask = stored.dynamic_mask;
  if (options.enlarged_dynamic_masks)
    f.enlarged_dynamic_mask = stored.enlarged_dynamic_mask;
  return f;
}
}  // namespace

Monst3rFolder Monst3rFolder::FromFrames(std::string name,
                                        std::string format,
                                        std::vector<Monst3rFrame> frames,
                                        GridResize resize,
                                        std::string units) {
  GEODRIVE_CHECK_INPUT(!frames.empty(), name, ": no frames");
  Monst3rFolder folder;
  folder.dir_ = std::move(name);
  folder.format_ = std::move(format);
  folder.units_ = std::move(units);
  folder.grid_resize_ = resize;
  const Monst3rFrame& f0 = frames.front();
  GEODRIVE_CHECK_INPUT(f0.depth.type() == CV_32FC1 && !f0.depth.empty(),
                       folder.dir_, ": frame 0 has no float32 depth map");
  folder.width_ = f0.depth.cols;
  folder.height_ = f0.depth.rows;
  folder.has_rgb_ = !f0.rgb.empty();
  folder.has_conf_ = !f0.confidence01.empty();
  folder.has_masks_ = !f0.dynamic_mask.empty();
  for (size_t i = 0; i < frames.size(); ++i) {
    Monst3rFrame& f = frames[i];
    const std::string what = folder.dir_ + " frame " + std::to_string(i);
    f.index = static_cast<int>(i);
    auto check = [&](const cv::Mat& m, int type, bool want, const char* kind) {
      GEODRIVE_CHECK_INPUT(
          m.empty() != want, what, ": ", kind,
          want ? " missing (frame 0 has one)" : " present (frame 0 has none)");
      if (!want) return;
      GEODRIVE_CHECK_INPUT(m.type() == type && m.cols == folder.width_ &&
                               m.rows == folder.height_,
                           what, ": ", kind, " is ", m.cols, "x", m.rows,
                           ", expected ", folder.width_, "x", folder.height_,
                           " like the depth of frame 0");
    };
    check(f.depth, CV_32FC1, true, "depth");
    check(f.rgb, CV_8UC3, folder.has_rgb_, "image");
    check(f.confidence01, CV_32FC1, folder.has_conf_, "confidence");
    check(f.dynamic_mask, CV_8UC1, folder.has_masks_, "dynamic mask");
    f.camera.Check(what + " intrinsics");
    GEODRIVE_CHECK_INPUT(f.world_from_cam.translation.allFinite() &&
                             f.world_from_cam.rotation.coeffs().allFinite(),
                         what, ": pose is not finite");
    folder.cameras_.push_back(f.camera);
    folder.trajectory_.Add(static_cast<double>(i), f.world_from_cam);
  }
  folder.memory_ =
      std::make_shared<const std::vector<Monst3rFrame>>(std::move(frames));
  return folder;
}

ImageResizeSpec Monst3rFolder::SourceToGrid(int in_width, int in_height) const {
  if (grid_resize_ == GridResize::kCenterCrop)
    return ComputeResizeSpec(in_width, in_height, width_, height_,
                             ResizeMode::kCenterCrop);
  if (grid_resize_ != GridResize::kStretch)
    return ComputeGridResizeSpec(grid_resize_, in_width, in_height);
  ImageResizeSpec s;
  s.resized_width = s.width = width_;
  s.resized_height = s.height = height_;
  return s;
}

Monst3rFolder Monst3rFolder::Open(const std::string& dir) {
  GEODRIVE_CHECK_INPUT(fs::is_directory(dir), dir,
                       ": not a directory (expected a MonST3R output "
                       "folder)");
  static const std::regex kDepth(R"(frame_(\d+)\.npy)"),
      kRgb(R"(frame_(\d+)\.png)"), kConf(R"(conf_(\d+)\.npy)"),
      kInit(R"(init_conf_(\d+)\.npy)"), kMask(R"(dynamic_mask_(\d+)\.png)"),
      kEnl(R"(enlarged_dynamic_mask_(\d+)\.png)"), kPts(R"(pts3d_(\d+)\.npy)");
  FileSet depth, rgb, conf, init, mask, enl, pts;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    std::smatch m;
    auto add = [&](FileSet& set) {
      // Integer after the last '_' (unpadded or padded alike).
      const int index = std::stoi(m[1].str().substr(0, 9));
      auto [it, inserted] = set.files.emplace(index, name);
      if (!inserted) {
        ThrowInputError(JoinPath(dir, name), "duplicate frame index ", index,
                        " (also ", it->second, ")");
      }
    };
    if (std::regex_match(name, m, kDepth))
      add(depth);
    else if (std::regex_match(name, m, kRgb))
      add(rgb);
    else if (std::regex_match(name, m, kConf))
      add(conf);
    else if (std::regex_match(name, m, kInit))
      add(init);
    else if (std::regex_match(name, m, kMask))
      add(mask);
    else if (std::regex_match(name, m, kEnl))
      add(enl);
    else if (std::regex_match(name, m, kPts))
      add(pts);
  }

  Monst3rFolder folder;
  folder.dir_ = dir;
  const std::string traj_path = JoinPath(dir, "pred_traj.txt");
  GEODRIVE_CHECK_INPUT(fs::exists(traj_path), traj_path,
                       ": missing (every MonST3R folder has the "
                       "camera-to-world trajectory)");
  folder.trajectory_ = ReadMonst3rTrajectory(traj_path);
  const int n = static_cast<int>(folder.trajectory_.size());
  GEODRIVE_CHECK_INPUT(n > 0, traj_path, ": no poses");
  for (int i = 0; i < n; ++i) {
    const Rigid3d& p = folder.trajectory_.world_from_cam[i];
    GEODRIVE_CHECK_INPUT(
        p.IsValid(1e-3), traj_path, ": pose ", i,
        " is not finite or its quaternion is not unit (NaN pose)");
  }
  GEODRIVE_CHECK_INPUT(
      !depth.empty(), JoinPath(dir, "frame_0000.npy"),
      ": missing (no depth maps frame_%04d.npy in the folder)");
  const std::string counted = "pred_traj.txt";
  CheckCoverage(dir, depth, n, "frame_{i}.npy", counted);
  // The depth files may be zero-padded (always are for MonST3R); report with
  // their real names.
  auto check_optional = [&](const FileSet& set, const std::string& pattern) {
    if (!set.empty()) CheckCoverage(dir, set, n, pattern, counted);
    return !set.empty();
  };
  folder.has_rgb_ = check_optional(rgb, "frame_{i}.png");
  folder.has_conf_ = check_optional(conf, "conf_{i}.npy");
  folder.has_init_conf_ = check_optional(init, "init_conf_{i}.npy");
  folder.has_masks_ = check_optional(mask, "dynamic_mask_{i}.png");
  folder.has_enlarged_masks_ =
      check_optional(enl, "enlarged_dynamic_mask_{i}.png");
  folder.has_pts3d_ = check_optional(pts, "pts3d_{i}.npy");

  const std::string depth0 = JoinPath(dir, depth.files.at(0));
  const NpyHeader header = ReadNpyHeader(depth0);
  GEODRIVE_CHECK_INPUT(header.shape.size() == 2 && header.shape[0] > 0 &&
                           header.shape[1] > 0 && header.shape[0] <= 16384 &&
                           header.shape[1] <= 16384,
                       depth0, ": expected an (H, W) depth map");
  folder.height_ = static_cast<int>(header.shape[0]);
  folder.width_ = static_cast<int>(header.shape[1]);

  const std::string intr_path = JoinPath(dir, "pred_intrinsics.txt");
  const std::string focal_path = JoinPath(dir, "pred_focal.txt");
  if (fs::exists(intr_path)) {
    folder.cameras_ =
        ReadMonst3rIntrinsics(intr_path, folder.width_, folder.height_);
    if (folder.cameras_.size() == 1 && n > 1)
      folder.cameras_.resize(n, folder.cameras_[0]);
    GEODRIVE_CHECK_INPUT(static_cast<int>(folder.cameras_.size()) == n,
                         intr_path, ": ", folder.cameras_.size(), " rows but ",
                         n,
                         " poses in pred_traj.txt (mismatched frame counts)");
  } else if (fs::exists(focal_path)) {
    // pose_eval.py layout: one focal per line, principal point at the image
    // centre.
    InputFileStream in(focal_path);
    std::string line;
    while (std::getline(in, line)) {
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      std::istringstream ls(line);
      double f = 0;
      GEODRIVE_CHECK_INPUT(
          static_cast<bool>(ls >> f) && std::isfinite(f) && f > 0, focal_path,
          ": bad focal '", line, "'");
      folder.cameras_.emplace_back(f, f, folder.width_ / 2.0,
                                   folder.height_ / 2.0, folder.width_,
                                   folder.height_);
    }
    GEODRIVE_CHECK_INPUT(static_cast<int>(folder.cameras_.size()) == n,
                         focal_path, ": ", folder.cameras_.size(),
                         " focals but ", n, " poses in pred_traj.txt");
  } else {
    ThrowInputError(intr_path, "missing (and no pred_focal.txt either)");
  }
  for (int i = 0; i < n; ++i)
    folder.cameras_[i].Check(intr_path + " row " + std::to_string(i));

  // Keep the scanned names (padding as found).
  folder.names_depth_ = std::move(depth.files);
  folder.names_rgb_ = std::move(rgb.files);
  folder.names_conf_ = std::move(conf.files);
  folder.names_init_ = std::move(init.files);
  folder.names_mask_ = std::move(mask.files);
  folder.names_enl_ = std::move(enl.files);
  folder.names_pts_ = std::move(pts.files);
  return folder;
}

namespace {
std::string NameOr(const std::map<int, std::string>& names,
                   int i,
                   const std::string& fallback) {
  auto it = names.find(i);
  return it != names.end() ? it->second : fallback;
}
std::string Pad4(int i) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%04d", i);
  return buf;
}
}  // namespace

std::string Monst3rFolder::DepthPath(int i) const {
  if (memory_) return "";
  return JoinPath(dir_, NameOr(names_depth_, i, "frame_" + Pad4(i) + ".npy"));
}
std::string Monst3rFolder::RgbPath(int i) const {
  if (memory_) return "";
  return JoinPath(dir_, NameOr(names_rgb_, i, "frame_" + Pad4(i) + ".png"));
}
std::string Monst3rFolder::ConfidencePath(int i) const {
  if (memory_) return "";
  return JoinPath(dir_,
                  NameOr(names_conf_, i, "conf_" + std::to_string(i) + ".npy"));
}
std::string Monst3rFolder::InitConfidencePath(int i) const {
  if (memory_) return "";
  return JoinPath(
      dir_, NameOr(names_init_, i, "init_conf_" + std::to_string(i) + ".npy"));
}
std::string Monst3rFolder::DynamicMaskPath(int i) const {
  if (memory_) return "";
  return JoinPath(dir_, NameOr(names_mask_, i,
                               "dynamic_mask_" + std::to_string(i) + ".png"));
}
std::string Monst3rFolder::EnlargedDynamicMaskPath(int i) const {
  if (memory_) return "";
  return JoinPath(
      dir_, NameOr(names_enl_, i,
                   "enlarged_dynamic_mask_" + std::to_string(i) + ".png"));
}
std::string Monst3rFolder::RawPointmapPath(int i) const {
  if (memory_) return "";
  return JoinPath(dir_,
                  NameOr(names_pts_, i, "pts3d_" + std::to_string(i) + ".npy"));
}

Monst3rFrame Monst3rFolder::LoadFrame(int i,
                                      const Monst3rLoadOptions& options) const {
  GEODRIVE_CHECK_INPUT(i >= 0 && i < num_frames(), dir_, ": frame ", i,
                       " out of range (", num_frames(), " frames)");
  if (memory_) return LoadMemoryFrame((*memory_)[i], options);
  Monst3rFrame frame;
  frame.index = i;
  frame.camera = cameras_[i];
  frame.world_from_cam = trajectory_.world_from_cam[i];
  const std::string depth_path = DepthPath(i);
  frame.depth =
      ReadFloatMapOfShape(depth_path, 1, width_, height_, "frame_0000.npy");
  const std::string ref =
      "the depth map " + fs::path(depth_path).filename().string();
  if (options.rgb && has_rgb_) {
    frame.rgb = ReadImageRgb(RgbPath(i));
    CheckShape(frame.rgb, width_, height_, RgbPath(i), ref);
  }
  auto read_conf = [&](const std::string& path) {
    cv::Mat conf = ReadFloatMapOfShape(path, 1, width_, height_, ref);
    if (options.reject_all_invalid_confidence) {
      bool any = false;
      for (int r = 0; r < conf.rows && !any; ++r) {
        const float* p = conf.ptr<float>(r);
        for (int c = 0; c < conf.cols; ++c) {
          if (std::isfinite(p[c])) {
            any = true;
            break;
          }
        }
      }
      if (!any) {
        // Name what the map holds: MonST3R writes -inf where it has no
        // confidence; +inf or NaN everywhere means a broken writer.
        const float v = conf.at<float>(0, 0);
        ThrowInputError(path, "confidence is not finite at any pixel (",
                        std::isnan(v) ? "NaN" : (v > 0 ? "+inf" : "-inf"),
                        " at pixel 0, 0)");
      }
    }
    return conf;
  };
  if (options.confidence && has_conf_)
    frame.log_confidence = read_conf(ConfidencePath(i));
  if (options.init_confidence && has_init_conf_) {
    frame.init_log_confidence = read_conf(InitConfidencePath(i));
  }
  if (options.dynamic_masks && has_masks_) {
    frame.dynamic_mask = ReadMask(DynamicMaskPath(i), width_, height_, ref);
  }
  if (options.enlarged_dynamic_masks && has_enlarged_masks_) {
    frame.enlarged_dynamic_mask =
        ReadMask(EnlargedDynamicMaskPath(i), width_, height_, ref);
  }
  if (options.raw_pointmaps && has_pts3d_) {
    frame.raw_points_in_world =
        ReadFloatMapOfShape(RawPointmapPath(i), 3, width_, height_, ref);
  }
  return frame;
}

std::vector<Monst3rFrame> Monst3rFolder::LoadFrames(
    const std::vector<int>& indices, const Monst3rLoadOptions& options) const {
  std::vector<Monst3rFrame> frames(indices.size());
  std::string error;
  bool failed = false;
#pragma omp parallel for schedule(dynamic)
  for (size_t k = 0; k < indices.size(); ++k) {
    try {
      frames[k] = LoadFrame(indices[k], options);
    } catch (const InputError& e) {
#pragma omp critical
      if (!failed) {
        failed = true;
        error = e.what();
      }
    }
  }
  if (failed) throw InputError(error);
  return frames;
}

std::vector<int> ParseFrameList(const std::string& text, int num_frames) {
  std::vector<int> out;
  if (text.empty() || text == "all") {
    for (int i = 0; i < num_frames; ++i) out.push_back(i);
    return out;
  }
  std::stringstream ss(text);
  std::string item;
  static const std::regex kRange(
      R"(\s*(\d+)\s*\.\.\s*(\d+)\s*(?::\s*(\d+))?\s*)"),
      kSingle(R"(\s*(\d+)\s*)");
  while (std::getline(ss, item, ',')) {
    std::smatch m;
    if (std::regex_match(item, m, kRange)) {
      const int a = std::stoi(m[1].str().substr(0, 9)),
                b = std::stoi(m[2].str().substr(0, 9));
      const int step = m[3].matched ? std::stoi(m[3].str().substr(0, 9)) : 1;
      GEODRIVE_CHECK_INPUT(step > 0 && a <= b, "--frames '", text,
                           "': bad range '", item, "'");
      for (int i = a; i <= b; i += step) out.push_back(i);
    } else if (std::regex_match(item, m, kSingle)) {
      out.push_back(std::stoi(m[1].str().substr(0, 9)));
    } else {
      ThrowInputError("--frames '" + text + "'", "cannot parse '", item,
                      "' (expected e.g. 0..24, 0,3,5 or 0..24:2)");
    }
  }
  for (int i : out) {
    GEODRIVE_CHECK_INPUT(i >= 0 && i < num_frames, "--frames '", text,
                         "': frame ", i, " out of range (", num_frames,
                         " frames)");
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

RawPointmap ReadRawPointmap(const std::string& points_path,
                            const std::string& confidence_path,
                            ConfidenceEncoding encoding) {
  RawPointmap out;
  const NpyArray array = ReadNpyAsFloat32(points_path);
  GEODRIVE_CHECK_INPUT(
      array.shape.size() == 3 && (array.shape[2] == 3 || array.shape[2] == 6),
      points_path, ": expected an (H, W, 3) or (H, W, 6) pointmap");
  const int h = static_cast<int>(array.shape[0]),
            w = static_cast<int>(array.shape[1]);
  const int c = static_cast<int>(array.shape[2]);
  GEODRIVE_CHECK_INPUT(h > 0 && w > 0, points_path, ": empty pointmap");
  out.points_in_world.create(h, w, CV_32FC3);
  if (c == 6) out.rgb.create(h, w, CV_8UC3);
  const float* data = array.Data<float>();
  for (int r = 0; r < h; ++r) {
    auto* p = out.points_in_world.ptr<cv::Vec3f>(r);
    for (int col = 0; col < w; ++col) {
      const float* src = data + (static_cast<size_t>(r) * w + col) * c;
      p[col] = cv::Vec3f(src[0], src[1], src[2]);
      if (c == 6) {
        auto& px = out.rgb.at<cv::Vec3b>(r, col);
        for (int k = 0; k < 3; ++k) {
          const float v = std::isfinite(src[3 + k]) ? src[3 + k] : 0.f;
          px[k] = static_cast<uint8_t>(
              std::lround(std::clamp(v, 0.f, 1.f) * 255.f));
        }
      }
    }
  }
  if (!confidence_path.empty()) {
    cv::Mat conf = ReadFloatMapOfShape(confidence_path, 1, w, h,
                                       "the pointmap " + points_path);
    out.confidence01 = ConfidenceMapToUnit(conf, encoding);
  }
  return out;
}

}  // namespace geodrive
