#include "diffusion/pairs_loader.h"

#include <algorithm>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <random>
#include <utility>

#include "geometry/util/status.h"
#include "render/video/video_io.h"

namespace geodrive {
namespace diffusion {

void PairsLoaderOptions::Check() const {
  GEODRIVE_CHECK_INPUT(!manifest.empty(), "--pairs is required");
  GEODRIVE_CHECK_INPUT(frames >= 1 && frames <= 10000, manifest,
                       ": loader frames must be in [1, 10000], got ", frames);
  GEODRIVE_CHECK_INPUT(
      width >= 1 && height >= 1 && width <= 16384 && height <= 16384, manifest,
      ": loader size ", width, "x", height, " out of range");
  GEODRIVE_CHECK_INPUT(resize_mode == "pair" || resize_mode == "resize" ||
                           resize_mode == "center-crop",
                       "resize mode must be pair, resize or center-crop, got '",
                       resize_mode, "'");
  GEODRIVE_CHECK_INPUT(prefetch >= 1 && prefetch <= 1024,
                       "prefetch must be in [1, 1024]");
  GEODRIVE_CHECK_INPUT(start_sample >= 0, "start sample must be >= 0");
}

std::vector<int64_t> EpochOrder(int64_t n,
                                uint64_t seed,
                                int64_t epoch,
                                bool shuffle) {
  std::vector<int64_t> order(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i) order[static_cast<size_t>(i)] = i;
  if (!shuffle || n < 2) return order;
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull +
                      static_cast<uint64_t>(epoch) * 0xBF58476D1CE4E5B9ull +
                      0x94D049BB133111EBull);
  // Fisher-Yates with an explicit modulo draw (std::uniform_int_distribution
  // differs between standard libraries).
  for (int64_t i = n - 1; i > 0; --i) {
    const int64_t j =
        static_cast<int64_t>(rng() % static_cast<uint64_t>(i + 1));
    std::swap(order[static_cast<size_t>(i)], order[static_cast<size_t>(j)]);
  }
  return order;
}

std::vector<cv::Mat> PrepareClip(const std::vector<cv::Mat>& frames,
                                 int count,
                                 int width,
                                 int height,
                                 const std::string& mode,
                                 const std::string& what) {
  GEODRIVE_CHECK_INPUT(!frames.empty(), what, ": no frames");
  GEODRIVE_CHECK_INPUT(mode == "resize" || mode == "center-crop", what,
                       ": unknown resize mode '", mode, "'");
  std::vector<cv::Mat> out;
  out.reserve(static_cast<size_t>(count));
  cv::Mat last;
  for (int i = 0; i < count; ++i) {
    if (i < static_cast<int>(frames.size())) {
      const cv::Mat& f = frames[static_cast<size_t>(i)];
      GEODRIVE_CHECK_INPUT(f.type() == CV_8UC3, what, ": frame ", i,
                           " is not 8-bit RGB");
      cv::Mat src = f;
      if (mode == "center-crop") {
        // Scale so the frame covers width x height, then crop the centre.
        const double s = std::max(static_cast<double>(width) / f.cols,
                                  static_cast<double>(height) / f.rows);
        const int w =
            std::max(width, static_cast<int>(std::lround(f.cols * s)));
        const int h =
            std::max(height, static_cast<int>(std::lround(f.rows * s)));
        cv::Mat scaled;
        cv::resize(f, scaled, cv::Size(w, h), 0, 0,
                   s < 1 ? cv::INTER_AREA : cv::INTER_CUBIC);
        src =
            scaled(cv::Rect((w - width) / 2, (h - height) / 2, width, height));
      }
      cv::Mat sized;
      if (src.cols == width && src.rows == height) {
        sized = src;
      } else {
        const bool down = src.cols > width || src.rows > height;
        cv::resize(src, sized, cv::Size(width, height), 0, 0,
                   down ? cv::INTER_AREA : cv::INTER_LINEAR);
      }
      cv::Mat converted;  // a fresh buffer: padding frames share `last`
      sized.convertTo(converted, CV_32FC3, 1.0 / 127.5, -1.0);
      last = converted;
    }
    // Padding repeats the last decoded frame (upstream: 25 -> 49).
    out.push_back(last);
  }
  return out;
}

PairSample LoadPairSample(const PairRecord& record,
                          const PairsLoaderOptions& options) {
  const std::string mode = options.resize_mode == "pair"
                               ? record.meta.resize_mode
                               : options.resize_mode;
  GEODRIVE_CHECK_INPUT(mode == "resize" || mode == "center-crop",
                       record.dir + "/meta.json", ": resize_mode '", mode,
                       "' is not resize or center-crop");
  PairSample s;
  s.clip_id = record.entry.clip_id;
  const std::vector<cv::Mat> gt = ReadVideoFrames(record.gt_video);
  const std::vector<cv::Mat> cond = ReadVideoFrames(record.cond_video);
  GEODRIVE_CHECK_INPUT(gt.size() == cond.size(), record.cond_video, ": has ",
                       cond.size(), " frames, the GT video ", gt.size());
  s.source_frames = static_cast<int>(gt.size());
  s.gt = PrepareClip(gt, options.frames, options.width, options.height, mode,
                     record.gt_video);
  s.cond = PrepareClip(cond, options.frames, options.width, options.height,
                       mode, record.cond_video);
  return s;
}

PairsLoader::PairsLoader(const PairsLoaderOptions& options)
    : options_(options) {
  options_.Check();
  const std::string build_dir =
      std::filesystem::path(options_.manifest).parent_path().string();
  for (const ManifestEntry& e : ReadManifest(options_.manifest)) {
    records_.push_back(ReadPair(build_dir.empty() ? "." : build_dir, e));
  }
  GEODRIVE_CHECK_INPUT(!records_.empty(), options_.manifest,
                       ": no pairs in the manifest");
  worker_ = std::thread([this] { Work(); });
}

PairsLoader::~PairsLoader() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();
}

void PairsLoader::Work() {
  const int64_t n = size();
  int64_t k = options_.start_sample;
  const int64_t end = options_.num_samples < 0
                          ? -1
                          : options_.start_sample + options_.num_samples;
  int64_t cached_epoch = -1;
  std::vector<int64_t> order;
  try {
    while (end < 0 || k < end) {
      const int64_t epoch = k / n;
      if (epoch != cached_epoch) {
        order = EpochOrder(n, options_.seed, epoch, options_.shuffle);
        cached_epoch = epoch;
      }
      const int64_t idx = order[static_cast<size_t>(k % n)];
      PairSample s =
          LoadPairSample(records_[static_cast<size_t>(idx)], options_);
      s.sample = k;
      s.pair_index = idx;
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [&] {
        return stop_ || static_cast<int>(queue_.size()) < options_.prefetch;
      });
      if (stop_) return;
      queue_.push_back(std::move(s));
      max_queued_ = std::max(max_queued_, static_cast<int>(queue_.size()));
      lock.unlock();
      cv_.notify_all();
      ++k;
    }
  } catch (...) {
    std::lock_guard<std::mutex> lock(mu_);
    error_ = std::current_exception();
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    done_ = true;
  }
  cv_.notify_all();
}

bool PairsLoader::Next(PairSample* sample) {
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait(lock, [&] { return !queue_.empty() || done_; });
  if (queue_.empty()) {
    if (error_) std::rethrow_exception(error_);
    return false;
  }
  *sample = std::move(queue_.front());
  queue_.pop_front();
  ++delivered_;
  lock.unlock();
  cv_.notify_all();
  return true;
}

int PairsLoader::max_queued() const {
  std::lock_guard<std::mutex> lock(mu_);
  return max_queued_;
}

}  // namespace diffusion
}  // namespace geodrive
