// The gen3c export (dataset/exporter.h): the input GEN3C's dynamic-video
// inference reads (nv-tlabs/GEN3C, cosmos_predict1/diffusion/inference/
// gen3c_dynamic.py), as docs/reference/trainer-formats.md §1 cites it
// ("GEN3C" there). Per clip, PAIR/gen3c/ (linked as OUT/gen3c/<clip>/):
//
//   rgb.mp4      the camera frames, H.264 at the pair videos' --x264-preset
//                and --crf (read with cv2.VideoCapture,
//                data_loader_utils.py:142-153); built at GEN3C's size, a
//                hard link to the pair's gt.mp4
//   depth.npz    depth (T,H,W) float32: the condition's z-depth in metres,
//                0 where no point was drawn or beyond 100 m (GEN3C maps NaN
//                to 100 and clamps to [0, 100]: cache_3d.py:107-108)
//   mask.npz     mask (T,H,W) bool: depth > 0 (data_loader_utils.py:157)
//   camera.npz   w2c (T,4,4) float32 = cam_from_world, OpenCV axes, in the
//                scene frame (camera 0 at frame 0); intrinsics (T,3,3)
//                float32 K at H x W (data_loader_utils.py:160-162; float32
//                because the loader does not cast them)
//
// at 704x1280 (H x W, --height/--width: inference_utils.py:120-128; the
// folder path never resizes). GEN3C needs exactly --num_video_frames =
// 120 N + 1 frames (gen3c_dynamic.py:109-111); another length is refused.
// Finish: OUT/gen3c/<clip> links and OUT/gen3c/batch.jsonl, one
// {"visual_input": <clip folder>} per clip for --batch_input_path
// (cosmos_predict1/utils/io.py:24-38; an absent prompt is "").

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "dataset/exporter.h"
#include "dataset/internal/exporters.h"
#include "dataset/pairs.h"
#include "geometry/npz.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"
#include "render/video/h264.h"

namespace geodrive {
namespace internal {
// Named: a unity build puts the exporters' files in one translation unit.
namespace gen3c_export {
namespace {

namespace fs = std::filesystem;

constexpr int kFirstFrames = 121, kFrameStep = 120;  // gen3c_dynamic.py:111
constexpr int kWidth = 1280, kHeight = 704;
constexpr double kFps = 24;  // --fps (the loader reads frames, not the rate)
constexpr float kMaxDepthM = 100.0f;  // cache_3d.py:107-108
constexpr char kFolder[] = "gen3c";

// depth (T,H,W) float32 and mask (T,H,W) bool: the condition's z-depth where
// it is in (0, 100], 0 and false elsewhere. The depth is written from the
// render's own frames (no 0.44 GB array assembled for a 121-frame clip); a
// frame with a value out of that range is written from a cleaned copy.
void WriteDepthAndMask(const std::string& dir, const ExportClip& clip) {
  const int64_t t = static_cast<int64_t>(clip.depth->size());
  const size_t pixels = static_cast<size_t>(kWidth) * kHeight;
  NpyPieces depth{NpyDtype::kFloat32, {t, kHeight, kWidth}, {}};
  NpyPieces mask{NpyDtype::kBool, {t, kHeight, kWidth}, {}};
  std::vector<cv::Mat> cleaned(t);
  std::vector<std::vector<uint8_t>> masks(t, std::vector<uint8_t>(pixels));
  for (int64_t i = 0; i < t; ++i) {
    const cv::Mat& src = (*clip.depth)[i];
    GEODRIVE_CHECK_INPUT(
        src.size() == cv::Size(kWidth, kHeight) && src.type() == CV_32F,
        clip.clip_id, ": gen3c needs the depth at ", kWidth, "x", kHeight,
        " (float); frame ", i, " is ", src.cols, "x", src.rows);
    uint8_t* m = masks[i].data();
    bool in_range = src.isContinuous();
    for (int y = 0; y < kHeight; ++y) {
      const float* row = src.ptr<float>(y);
      for (int x = 0; x < kWidth; ++x) {
        const bool kept = row[x] > 0 && row[x] <= kMaxDepthM;
        m[static_cast<size_t>(y) * kWidth + x] = kept;
        in_range &= kept || row[x] == 0;
      }
    }
    if (!in_range) {
      cleaned[i] = cv::Mat(kHeight, kWidth, CV_32F, cv::Scalar(0));
      src.copyTo(cleaned[i], cv::Mat(kHeight, kWidth, CV_8U, m));
    }
    const cv::Mat& d = in_range ? src : cleaned[i];
    depth.pieces.emplace_back(d.data, pixels * sizeof(float));
    mask.pieces.emplace_back(m, pixels);
  }
  // Stored, not deflated (numpy.savez): deflating a 121-frame clip's depth
  // and mask took tens of seconds (the mask alone 20 s) for disk space.
  WriteNpz(dir + "/depth.npz", {{"depth", std::move(depth)}},
           /*compress=*/false);
  WriteNpz(dir + "/mask.npz", {{"mask", std::move(mask)}}, /*compress=*/false);
}

// w2c (T,4,4) and intrinsics (T,3,3), float32.
void WriteCameras(const std::string& dir, const ExportClip& clip) {
  const int64_t t = static_cast<int64_t>(clip.world_from_cam.size());
  std::vector<float> w2c, k;
  const Eigen::Matrix3d K = clip.camera.K();
  for (const Rigid3d& pose : clip.world_from_cam) {
    const Eigen::Matrix4d m = pose.Inverse().ToMatrix();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) w2c.push_back(static_cast<float>(m(r, c)));
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) k.push_back(static_cast<float>(K(r, c)));
  }
  WriteNpz(dir + "/camera.npz",
           {{"w2c", NpyArray::Float32({t, 4, 4}, w2c.data())},
            {"intrinsics", NpyArray::Float32({t, 3, 3}, k.data())}});
}

// rgb.mp4: a hard link to the pair's video of the same frames where there is
// one (built at 704x1280 centre-cropped; it plays at the pair's --fps, which
// the loader does not read), else the frames encoded at kFps.
void WriteRgbVideo(const std::string& path, const ExportClip& clip) {
  if (!clip.images_video.empty()) {
    std::error_code ec;
    fs::remove(path, ec);
    fs::create_hard_link(clip.images_video, path, ec);
    if (!ec) return;
  }
  H264Options vo;
  vo.fps = kFps;
  vo.preset = clip.video_preset;
  vo.crf = clip.video_crf;
  WriteH264Mp4(path, *clip.images, vo);
}

class Gen3cExporter : public Exporter {
 public:
  ExportFormat Format() const override { return ExportFormat::kGen3c; }

  ExportRequirements Requirements() const override {
    ExportRequirements req;
    req.min_frames = kFirstFrames;
    req.frame_step = kFrameStep;
    req.width = kWidth;
    req.height = kHeight;
    req.fps = kFps;
    req.depth = true;
    return req;
  }

  void WriteClip(const ExportClip& clip,
                 const std::string& pair_dir,
                 PairMeta* meta) const override {
    const int n = static_cast<int>(clip.images->size());
    CheckClipForExport(*this, clip.clip_id, n);
    GEODRIVE_CHECK_INPUT(static_cast<int>(clip.depth->size()) == n &&
                             static_cast<int>(clip.world_from_cam.size()) == n,
                         clip.clip_id,
                         ": gen3c needs a depth and a pose per frame; ", n,
                         " frames, ", clip.depth->size(), " depths, ",
                         clip.world_from_cam.size(), " poses");
    for (const cv::Mat& image : *clip.images) {
      GEODRIVE_CHECK_INPUT(image.size() == cv::Size(kWidth, kHeight),
                           clip.clip_id, ": gen3c needs frames at ", kWidth,
                           "x", kHeight, ", got ", image.cols, "x", image.rows);
    }
    const std::string dir = pair_dir + "/" + kFolder;
    fs::create_directories(dir);
    WriteRgbVideo(dir + "/rgb.mp4", clip);
    WriteDepthAndMask(dir, clip);
    WriteCameras(dir, clip);
    meta->files[kFolder] = kFolder;
  }

  int Finish(const std::string& out) const override;
};

int Gen3cExporter::Finish(const std::string& out) const {
  const std::string root = out + "/" + kFolder;
  const std::vector<std::string> clips =
      internal::PairsWithExport(out, kFolder);
  if (clips.empty() && !fs::exists(root)) return 0;
  fs::create_directories(root);
  std::string batch;
  for (const std::string& c : clips) {
    const fs::path link = fs::path(root) / c;
    std::error_code ec;
    fs::remove(link, ec);
    fs::create_directory_symlink(fs::path("..") / "pairs" / c / kFolder, link,
                                 ec);
    GEODRIVE_CHECK_INPUT(!ec, link.string(), ": cannot create link (",
                         ec.message(), ")");
    nlohmann::json line;
    line["visual_input"] = fs::absolute(link).lexically_normal().string();
    batch += line.dump() + "\n";
  }
  WriteFileAtomic(root + "/batch.jsonl", batch);
  return static_cast<int>(clips.size());
}

}  // namespace
}  // namespace gen3c_export

std::unique_ptr<Exporter> CreateGen3cExporter(const ExportOptions& options) {
  (void)options;  // no split: GEN3C has no train/val lists
  return std::make_unique<gen3c_export::Gen3cExporter>();
}

}  // namespace internal
}  // namespace geodrive
