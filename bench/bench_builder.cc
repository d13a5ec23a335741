// The builder's frame path (dataset/frame_decode.h) on real files: for every
// JPEG/PNG under the given folders, the present path (kDctScaled: decode at a
// DCT scale + exact area resize) and the same choosing from every M/8 scale
// (all_jpeg_scales) against the reference path (kFull: full decode +
// cv::resize INTER_AREA), CPU time per frame (this thread's clock, best of
// --repeat) and the PSNR of each output against kFull's. Figures:
// docs/PERFORMANCE.md "Dataset builder". --per-frame also prints each file's
// times and PSNR (to stderr).
//
//   bench_builder [--size HxW] [--mode resize|center-crop] [--repeat N]
//                 [--max-files N] [--per-frame] [--stages] DIR...
//
// --stages then times the parts on each folder (1600x900 JPEGs): the decode at
// 1/1, 5/8 and 1/2, and cv::resize(INTER_AREA) against AreaResizeRgb, from the
// full decode, from the 5/8 one and for a preview thumbnail of the 720x480
// frame (ms per frame, same clock).

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "dataset/frame_decode.h"
#include "geometry/camera.h"
#include "geometry/image_io.h"
#include "geometry/image_resize.h"
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

// Best-of-`repeat` CPU seconds of fn().
template <typename F>
double BestCpu(int repeat, F&& fn) {
  double best = std::numeric_limits<double>::infinity();
  for (int r = 0; r < repeat; ++r) {
    const double t0 = ThreadCpuSeconds();
    fn();
    best = std::min(best, ThreadCpuSeconds() - t0);
  }
  return best;
}

// --stages: where a path's time goes, per frame of a 1600x900 folder at
// 720x480 (resize mode): the decode at the scales in play and the resizes.
void PrintStages(const std::string& dir,
                 const std::vector<std::string>& files,
                 int repeat) {
  using geodrive::JpegScale;
  const JpegScale scales[] = {{1, 1}, {5, 8}, {1, 2}};
  double decode[3] = {0, 0, 0}, cv_area = 0, area_full = 0, area_58 = 0,
         cv_area_58 = 0, cv_thumb = 0, area_thumb = 0;
  const cv::Size out(720, 480);
  for (const std::string& f : files) {
    cv::Mat m[3];
    for (int i = 0; i < 3; ++i) {
      decode[i] += BestCpu(
          repeat, [&] { m[i] = geodrive::ReadImageRgbScaled(f, scales[i]); });
    }
    cv::Mat r;
    cv_area += BestCpu(repeat,
                       [&] { cv::resize(m[0], r, out, 0, 0, cv::INTER_AREA); });
    area_full += BestCpu(repeat, [&] {
      r = geodrive::AreaResizeRgb(m[0], m[0].cols, m[0].rows, out);
    });
    area_58 += BestCpu(
        repeat, [&] { r = geodrive::AreaResizeRgb(m[1], 1000, 562.5, out); });
    cv_area_58 += BestCpu(repeat, [&] {
      cv::resize(m[1], r, cv::Size(), 0.72, 480 / 562.5, cv::INTER_AREA);
    });
    // A preview.png thumbnail of the 720x480 output (18 a pair).
    const cv::Mat frame =
        geodrive::AreaResizeRgb(m[0], m[0].cols, m[0].rows, out);
    const cv::Size thumb(160, 107);
    cv_thumb += BestCpu(
        repeat, [&] { cv::resize(frame, r, thumb, 0, 0, cv::INTER_AREA); });
    area_thumb += BestCpu(
        repeat, [&] { r = geodrive::AreaResizeRgb(frame, 720, 480, thumb); });
  }
  const double k = 1e3 / std::max<size_t>(1, files.size());
  std::printf(
      "| %s | decode 1/1 %.2f, 5/8 %.2f, 1/2 %.2f | 1600x900 -> 720x480: "
      "cv::resize INTER_AREA %.2f, AreaResizeRgb %.2f | 1000x562.5 -> "
      "720x480: cv::resize INTER_AREA %.2f, AreaResizeRgb %.2f | 720x480 -> "
      "160x107: cv::resize INTER_AREA %.3f, AreaResizeRgb %.3f |\n",
      dir.c_str(), k * decode[0], k * decode[1], k * decode[2], k * cv_area,
      k * area_full, k * cv_area_58, k * area_58, k * cv_thumb, k * area_thumb);
}

int Run(int argc, char** argv) {
  int out_w = 720, out_h = 480, repeat = 3;
  size_t max_files = 0;
  bool per_frame = false, stages = false;
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
    } else if (a == "--per-frame") {
      per_frame = true;
    } else if (a == "--stages") {
      stages = true;
    } else {
      dirs.push_back(a);
    }
  }
  if (dirs.empty()) {
    std::fprintf(
        stderr,
        "usage: bench_builder [--size HxW] [--mode resize|center-crop] "
        "[--repeat N] [--max-files N] [--per-frame] [--stages] DIR...\n");
    return 2;
  }
  // The three paths, timed frame by frame in turn (so that load changes hit
  // all three alike): the full decode + cv::resize (the reference), the
  // builder's kDctScaled, and kDctScaled choosing from every M/8 scale.
  struct Path {
    const char* name;
    FrameDecodeOptions opt;
    double cpu_s = 0, psnr_min = 1e9, psnr_sum = 0, psnr_max = 0;
    geodrive::JpegScale scale;
  };
  std::vector<Path> paths(3);
  paths[0].name = "full decode + cv::resize (kFull)";
  paths[0].opt.mode = FrameDecodeMode::kFull;
  paths[1].name = "kDctScaled (default scales)";
  paths[2].name = "kDctScaled, all_jpeg_scales";
  paths[2].opt.all_jpeg_scales = true;
  std::printf(
      "| folder | frames | source | path | decode scale | ms per frame | "
      "speed-up | PSNR vs kFull min / mean / max, dB |\n"
      "|---|---|---|---|---|---|---|---|\n");
  for (const std::string& dir : dirs) {
    const std::vector<std::string> files = ImagesUnder(dir, max_files);
    for (Path& p : paths) {
      const Path fresh{p.name, p.opt, 0, 1e9, 0, 0, {}};
      p = fresh;
    }
    cv::Size full;
    for (const std::string& f : files) {
      full = geodrive::ReadImageSize(f);
      const auto spec = geodrive::ComputeResizeSpec(full.width, full.height,
                                                    out_w, out_h, mode);
      cv::Mat reference;
      for (Path& p : paths) {
        p.scale =
            geodrive::FrameDecodeScale(full.width, full.height, spec, p.opt);
        const PathTiming t = TimePath(f, full, spec, p.opt, repeat);
        p.cpu_s += t.best_cpu_s;
        if (reference.empty()) reference = t.out;
        const double psnr = Psnr(reference, t.out);
        p.psnr_min = std::min(p.psnr_min, psnr);
        p.psnr_max = std::max(p.psnr_max, psnr);
        p.psnr_sum += psnr;
        if (per_frame) {
          std::fprintf(stderr, "%s  %s  %.2f ms  %.2f dB\n", f.c_str(), p.name,
                       1e3 * t.best_cpu_s, psnr);
        }
      }
    }
    const double k = std::max<size_t>(1, files.size());
    for (const Path& p : paths) {
      std::printf(
          "| %s | %zu | %dx%d | %s | %d/%d | %.2f | %.2fx | %.1f / %.1f / "
          "%.1f |\n",
          dir.c_str(), files.size(), full.width, full.height, p.name,
          p.scale.num, p.scale.denom, 1e3 * p.cpu_s / k,
          paths[0].cpu_s / std::max(p.cpu_s, 1e-12), p.psnr_min, p.psnr_sum / k,
          p.psnr_max);
    }
  }
  if (stages) {
    std::printf(
        "\n| folder | decode, ms per frame | resize from 1/1, ms | resize from "
        "5/8, ms | thumbnail, ms |\n|---|---|---|---|---|\n");
    for (const std::string& dir : dirs)
      PrintStages(dir, ImagesUnder(dir, max_files), repeat);
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
