// The builder's frame path (dataset/frame_decode.h) on real files: for every
// JPEG/PNG under the given folders, the present path (DCT-scaled decode +
// resize) against the previous one (full decode + INTER_AREA resize), CPU time
// per frame (this thread's clock, best of --repeat) and the PSNR between the
// two outputs. Figures: docs/PERFORMANCE.md "Dataset builder".
//
//   bench_builder [--size HxW] [--mode resize|center-crop] [--repeat N]
//                 [--max-files N] DIR...

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "dataset/frame_decode.h"
#include "geometry/camera.h"
#include "geometry/image_io.h"
#include "geometry/util/memory.h"

namespace {

namespace fs = std::filesystem;
using geodrive::FrameDecodeMode;
using geodrive::FrameDecodeOptions;

double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

// PSNR (dB, data range 255) over all channels; 100 for identical images.
double Psnr(const cv::Mat& a, const cv::Mat& b) {
  const double n = static_cast<double>(a.total()) * a.channels();
  const double norm = cv::norm(a, b, cv::NORM_L2);
  const double mse = norm * norm / n;
  return mse <= 0 ? 100.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

std::vector<std::string> ImagesUnder(const std::string& dir, size_t max_files) {
  std::vector<std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string ext = e.path().extension().string();
    if (e.is_regular_file() && (ext == ".jpg" || ext == ".png"))
      files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  if (max_files > 0 && files.size() > max_files) files.resize(max_files);
  return files;
}

struct PathTiming {
  double best_cpu_s = std::numeric_limits<double>::infinity();
  cv::Mat out;
};

PathTiming TimePath(const std::string& path,
                    const cv::Size& full,
                    const geodrive::ImageResizeSpec& spec,
                    const FrameDecodeOptions& opt,
                    int repeat) {
  PathTiming t;
  for (int r = 0; r < repeat; ++r) {
    const double t0 = ThreadCpuSeconds();
    t.out = geodrive::ReadFrameAtOutputSize(path, full.width, full.height, spec,
                                            opt);
    t.best_cpu_s = std::min(t.best_cpu_s, ThreadCpuSeconds() - t0);
  }
  return t;
}

int Run(int argc, char** argv) {
  int out_w = 720, out_h = 480, repeat = 3;
  size_t max_files = 0;
  geodrive::ResizeMode mode = geodrive::ResizeMode::kResize;
  std::vector<std::string> dirs;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--size" && has_value) {
      std::sscanf(argv[++i], "%dx%d", &out_h, &out_w);
    } else if (a == "--mode" && has_value) {
      mode = geodrive::ParseResizeMode(argv[++i]);
    } else if (a == "--repeat" && has_value) {
      repeat = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--max-files" && has_value) {
      max_files = std::strtoul(argv[++i], nullptr, 10);
    } else {
      dirs.push_back(a);
    }
  }
  if (dirs.empty()) {
    std::fprintf(
        stderr,
        "usage: bench_builder [--size HxW] [--mode resize|center-crop] "
        "[--repeat N] [--max-files N] DIR...\n");
    return 2;
  }
  FrameDecodeOptions old_opt, new_opt;
  old_opt.mode = FrameDecodeMode::kFull;
  std::printf(
      "| folder | frames | source | decode | full decode + resize, "
      "ms | DCT-scaled + resize, ms | speed-up | PSNR min / mean / "
      "max, dB |\n|---|---|---|---|---|---|---|---|\n");
  for (const std::string& dir : dirs) {
    const std::vector<std::string> files = ImagesUnder(dir, max_files);
    double old_s = 0, new_s = 0, psnr_min = 1e9, psnr_sum = 0, psnr_max = 0;
    cv::Size full;
    int denom = 1;
    for (const std::string& f : files) {
      full = geodrive::ReadImageSize(f);
      const auto spec = geodrive::ComputeResizeSpec(full.width, full.height,
                                                    out_w, out_h, mode);
      denom = geodrive::FrameDecodeDenominator(full.width, full.height, spec,
                                               new_opt);
      const PathTiming o = TimePath(f, full, spec, old_opt, repeat);
      const PathTiming n = TimePath(f, full, spec, new_opt, repeat);
      old_s += o.best_cpu_s;
      new_s += n.best_cpu_s;
      const double p = Psnr(o.out, n.out);
      psnr_min = std::min(psnr_min, p);
      psnr_max = std::max(psnr_max, p);
      psnr_sum += p;
    }
    const double k = std::max<size_t>(1, files.size());
    std::printf(
        "| %s | %zu | %dx%d | 1/%d | %.2f | %.2f | %.2fx | %.1f / "
        "%.1f / %.1f |\n",
        dir.c_str(), files.size(), full.width, full.height, denom,
        1e3 * old_s / k, 1e3 * new_s / k, old_s / std::max(new_s, 1e-12),
        psnr_min, psnr_sum / k, psnr_max);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  geodrive::ConfigureAllocatorForThroughput();
  cv::setNumThreads(1);
  try {
    return Run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_builder: %s\n", e.what());
    return 2;
  }
}
