// The streetcrafter export (dataset/exporter.h): what StreetCrafter's
// video-diffusion trainer (zju3dv/street_crafter, video_diffusion/train.py)
// reads, as docs/reference/trainer-formats.md §2 cites it ("SC" there):
//
//   DATA_ROOT/meta_info_{train,val}.json   JSON lists of samples
//     {"frames": [25], "guidances": [25], "guidances_mask": [25]}, paths
//     relative to DATA_ROOT (vwm/data/subsets/waymo.py:17-22,49-56;
//     common.py:25-26)
//
// Per clip, PAIR/streetcrafter/ (linked as OUT/streetcrafter/<clip>/):
//   images/%06d_0.jpg                 the camera frame, RGB JPEG (quality
//                                     95): upstream's frames are JPEG too,
//                                     each Waymo camera's bytes written as
//                                     they are (waymo_converter.py:146-150,
//                                     under .png names); the loader opens
//                                     them with PIL, by content (waymo.py:59)
//   lidar/color_render/%06d_0.png     the guidance: our condition (the
//                                     scene's points coloured from the
//                                     images, on black)
//   lidar/color_render/%06d_0_mask.png  1-bit gray, 1 = a point was drawn
//                                     (upstream writes 8-bit 0/255,
//                                     waymo_render_lidar_pcd.py:266,276-277;
//                                     the Waymo trainer does not read it, the
//                                     PandaSet one opens it with PIL and
//                                     convert("RGB"), which gives 0/255 from
//                                     either: pandaset.py:58-77,110-115)
//   lidar/depth/%06d_0.npz            metric scenes only: {mask (H,W) bool,
//                                     value float32 1-D = depth[mask], camera
//                                     z-depth in metres clipped to [0.1, 100]}
//                                     (waymo_get_lidar_pcd.py:243-275, read by
//                                     waymo_readers.py:126-134 in the 3DGS
//                                     stage only; no *_depth.npy is read)
//
// Frames and guidances are written at 576x320 (the low-res stage's target,
// configs/condition/waymo_low_res.yaml:214-226), so that the loader's crop
// and resize (waymo.py:58-77) are the identity. Samples are windows of 25
// consecutive frames starting every 5 frames (waymo_prepare_meta.py:54-57);
// a clip of fewer than 25 frames is refused: the trainer's sampler would skip
// its samples silently (dataset.py:135-141).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>

#include "dataset/exporter.h"
#include "dataset/internal/exporters.h"
#include "dataset/internal/pair_png.h"
#include "dataset/pairs.h"
#include "geometry/image_io.h"
#include "geometry/npz.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace internal {
namespace {

namespace fs = std::filesystem;

constexpr int kSampleFrames = 25;  // waymo.py:97-112
constexpr int kSampleStride = 5;   // waymo_prepare_meta.py:54-57
constexpr int kWidth = 576, kHeight = 320;
constexpr float kMinDepthM = 0.1f, kMaxDepthM = 100.0f;
// A 576x320 frame as JPEG at 95 takes under 1 ms, as PNG 10 ms (level 1).
constexpr int kJpegQuality = 95;
constexpr char kFolder[] = "streetcrafter";

std::string FrameName(int frame, const char* suffix) {
  char name[40];
  std::snprintf(name, sizeof(name), "%06d_0%s", frame, suffix);
  return name;
}

// {mask, value} as StreetCrafter's LiDAR depth: value = depth[mask] in
// row-major order of mask, clipped to [0.1, 100] m. Stored, not deflated
// (numpy.savez): deflating the float values took three quarters of a clip's
// export time for half the bytes (about 0.6 MB a 576x320 frame stored).
void WriteDepthNpz(const std::string& path, const cv::Mat& depth) {
  NpyArray mask = NpyArray::Zeros(NpyDtype::kBool, {depth.rows, depth.cols});
  uint8_t* m = mask.MutableData<uint8_t>();
  std::vector<float> value;
  for (int y = 0; y < depth.rows; ++y) {
    const float* d = depth.ptr<float>(y);
    for (int x = 0; x < depth.cols; ++x) {
      if (!(d[x] > 0) || !std::isfinite(d[x])) continue;
      m[static_cast<size_t>(y) * depth.cols + x] = 1;
      value.push_back(std::clamp(d[x], kMinDepthM, kMaxDepthM));
    }
  }
  WriteNpz(path,
           {{"mask", std::move(mask)},
            {"value", NpyArray::Float32({static_cast<int64_t>(value.size())},
                                        value.data())}},
           /*compress=*/false);
}

class StreetCrafterExporter : public Exporter {
 public:
  explicit StreetCrafterExporter(const ExportOptions& options)
      : options_(options) {}

  ExportFormat Format() const override { return ExportFormat::kStreetCrafter; }

  ExportRequirements Requirements() const override {
    ExportRequirements req;
    req.min_frames = kSampleFrames;
    req.width = kWidth;
    req.height = kHeight;
    req.fps = 10;  // Waymo; fps_id is fixed (waymo.py:82-91)
    req.depth = true;
    return req;
  }

  void WriteClip(const ExportClip& clip,
                 const std::string& pair_dir,
                 PairMeta* meta) const override {
    const int n = static_cast<int>(clip.images->size());
    CheckClipForExport(*this, clip.clip_id, n);
    const std::string dir = pair_dir + "/" + kFolder;
    fs::create_directories(dir + "/images");
    fs::create_directories(dir + "/lidar/color_render");
    if (clip.metric) fs::create_directories(dir + "/lidar/depth");
    for (int i = 0; i < n; ++i) {
      const cv::Mat& image = (*clip.images)[i];
      const cv::Mat& guidance = (*clip.condition)[i];
      GEODRIVE_CHECK_INPUT(
          image.size() == guidance.size() &&
              image.size() == cv::Size(kWidth, kHeight),
          clip.clip_id, ": streetcrafter needs frames and guidances at ",
          kWidth, "x", kHeight, "; frame ", i, " is ", image.cols, "x",
          image.rows, " and its guidance ", guidance.cols, "x", guidance.rows);
      WriteJpeg(dir + "/images/" + FrameName(i, ".jpg"), image, kJpegQuality);
      const std::string render = dir + "/lidar/color_render/";
      WritePairPng(render + FrameName(i, ".png"), guidance,
                   PngContent::kRender);
      WriteMaskPng(render + FrameName(i, "_mask.png"), (*clip.drawn)[i]);
      if (clip.metric) {
        WriteDepthNpz(dir + "/lidar/depth/" + FrameName(i, ".npz"),
                      (*clip.depth)[i]);
      }
    }
    meta->files[kFolder] = kFolder;
  }

  int Finish(const std::string& out) const override;

 private:
  ExportOptions options_;
};

int StreetCrafterExporter::Finish(const std::string& out) const {
  const std::string root = out + "/" + kFolder;
  struct Clip {
    std::string name, scene;
    int frames = 0;
  };
  std::vector<Clip> clips;
  for (const std::string& name : internal::PairsWithExport(out, kFolder)) {
    const PairMeta m = ReadPairMeta(out + "/pairs/" + name);
    clips.push_back({name, m.scene_name, static_cast<int>(m.frames.size())});
  }
  if (clips.empty() && !fs::exists(root)) return 0;
  std::set<std::string> scenes;
  for (const Clip& c : clips) scenes.insert(c.scene);
  const std::set<std::string> val = ValScenes(scenes, options_);
  fs::create_directories(root);
  nlohmann::json lists[2] = {nlohmann::json::array(), nlohmann::json::array()};
  int samples = 0;
  for (const Clip& c : clips) {
    const fs::path link = fs::path(root) / c.name;
    std::error_code ec;
    fs::remove(link, ec);
    fs::create_directory_symlink(fs::path("..") / "pairs" / c.name / kFolder,
                                 link, ec);
    GEODRIVE_CHECK_INPUT(!ec, link.string(), ": cannot create link (",
                         ec.message(), ")");
    for (int start = 0; start + kSampleFrames <= c.frames;
         start += kSampleStride) {
      nlohmann::json s;
      s["frames"] = s["guidances"] = s["guidances_mask"] =
          nlohmann::json::array();
      for (int i = start; i < start + kSampleFrames; ++i) {
        s["frames"].push_back(c.name + "/images/" + FrameName(i, ".jpg"));
        s["guidances"].push_back(c.name + "/lidar/color_render/" +
                                 FrameName(i, ".png"));
        s["guidances_mask"].push_back(c.name + "/lidar/color_render/" +
                                      FrameName(i, "_mask.png"));
      }
      lists[val.count(c.scene) ? 1 : 0].push_back(std::move(s));
      ++samples;
    }
  }
  // Both files always exist: the loader raises on a missing one
  // (waymo.py:27-30).
  WriteFileAtomic(root + "/meta_info_train.json", lists[0].dump(1) + "\n");
  WriteFileAtomic(root + "/meta_info_val.json", lists[1].dump(1) + "\n");
  return samples;
}

}  // namespace

std::unique_ptr<Exporter> CreateStreetCrafterExporter(
    const ExportOptions& options) {
  return std::make_unique<StreetCrafterExporter>(options);
}

}  // namespace internal
}  // namespace geodrive
