// The geodrive-upstream export (dataset/exporter.h): GeoDrive's released
// trainer (train.py) reads OUT/geodrive_upstream/meta.jsonl and
// sample_%06d/render_%d.png (docs/reference/formats.md).
//
// Per clip: PAIR/upstream/render_%d.png, 1024x576 RGB as the upstream renderer
// writes them (frame 0 = the real image, the others the renderer's frames
// before the resize to the pair's size). Finish: OUT/geodrive_upstream/
// sample_%06d links to those folders (numbered by the clip's index in the
// dataset's clip list) and meta.jsonl.

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "dataset/exporter.h"
#include "dataset/internal/exporters.h"
#include "dataset/internal/pair_png.h"
#include "dataset/pairs.h"
#include "geometry/image_io.h"
#include "geometry/image_resize.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace internal {
namespace {

// Writes DIR/upstream/render_%d.png as GeoDrive's upstream renderer does:
// 1024x576 RGB, frame 0 = the real image.
void WriteUpstreamFrames(const std::string& dir, const ExportClip& clip) {
  const cv::Size size(1024, 576);  // upstream: 288x512 render, x2 upsample
  const std::string up = dir + "/upstream";
  std::filesystem::create_directories(up);
  const std::vector<cv::Mat>& native = *clip.native_condition;
  for (size_t i = 0; i < native.size(); ++i) {
    // Frame 0 is the real image (upstream replaces it); the others are the
    // renderer's frames (exactly 576x1024 with the released preset).
    cv::Mat real;
    if (i == 0) {
      real = clip.first_frame_full.empty() ? ReadImageRgb(clip.first_frame_path)
                                           : clip.first_frame_full;
    }
    const cv::Mat& src = i == 0 ? real : native[i];
    cv::Mat f = src;
    if (f.size() != size) {
      // Shrinking: INTER_AREA's weights, several times faster than
      // cv::resize at the non-integer 1600x900 -> 1024x576.
      f = src.cols >= size.width && src.rows >= size.height &&
                  src.type() == CV_8UC3
              ? AreaResizeRgb(src, src.cols, src.rows, size)
              : cv::Mat();
      if (f.empty()) cv::resize(src, f, size, 0, 0, cv::INTER_LINEAR);
    }
    WritePairPng(up + "/render_" + std::to_string(i) + ".png", f,
                 i == 0 ? PngContent::kPhoto : PngContent::kRender);
  }
}

// Rebuilds OUT/geodrive_upstream/ (sample_%06d links and meta.jsonl) from the
// pair folders that have upstream frames. Returns the number of samples.
int WriteUpstreamIndex(const std::string& out) {
  namespace fs = std::filesystem;
  const std::string root = out + "/geodrive_upstream";
  std::vector<std::pair<int, std::string>> samples;  // scene_idx, jsonl line
  for (const std::string& name : internal::PairsWithExport(out, "upstream")) {
    const PairMeta m = ReadPairMeta(out + "/pairs/" + name);
    if (!m.upstream_scene_idx) continue;
    char sample[32];
    std::snprintf(sample, sizeof(sample), "sample_%06d", *m.upstream_scene_idx);
    const fs::path link = fs::path(root) / sample;
    fs::create_directories(root);
    std::error_code ec;
    fs::remove(link, ec);
    fs::create_directory_symlink(fs::path("..") / "pairs" / name / "upstream",
                                 link, ec);
    GEODRIVE_CHECK_INPUT(!ec, link.string(), ": cannot create link (",
                         ec.message(), ")");
    // Through the JSON library: file names from the tables are data (a
    // quote or a control byte in one is escaped, never written raw).
    nlohmann::json j;
    j["gt_frames"] = nlohmann::json::array();
    j["render_frames"] = nlohmann::json::array();
    for (size_t i = 0; i < m.frames.size(); ++i) {
      j["gt_frames"].push_back(m.frames[i].filename);
      j["render_frames"].push_back(std::string(sample) + "/render_" +
                                   std::to_string(i) + ".png");
    }
    j["scene_idx"] = *m.upstream_scene_idx;
    const std::string line = j.dump();
    samples.emplace_back(*m.upstream_scene_idx, line);
  }
  if (samples.empty() && !fs::exists(root)) return 0;
  fs::create_directories(root);
  std::sort(samples.begin(), samples.end());
  std::string text;
  for (const auto& [idx, line] : samples) text += line + "\n";
  WriteFileAtomic(root + "/meta.jsonl", text);
  return static_cast<int>(samples.size());
}

class GeodriveUpstreamExporter : public Exporter {
 public:
  ExportFormat Format() const override {
    return ExportFormat::kGeodriveUpstream;
  }
  ExportRequirements Requirements() const override {
    ExportRequirements req;
    req.native_condition = true;  // the released preset's 576x1024 frames
    return req;
  }
  void WriteClip(const ExportClip& clip,
                 const std::string& pair_dir,
                 PairMeta* meta) const override {
    WriteUpstreamFrames(pair_dir, clip);
    meta->files["upstream"] = "upstream";
    if (clip.clip_index >= 0) meta->upstream_scene_idx = clip.clip_index;
  }
  int Finish(const std::string& out) const override {
    return WriteUpstreamIndex(out);
  }
};

}  // namespace

std::unique_ptr<Exporter> CreateGeodriveUpstreamExporter(
    const ExportOptions& /*options*/) {
  return std::make_unique<GeodriveUpstreamExporter>();
}

}  // namespace internal
}  // namespace geodrive
