#pragma once
// Training-pair loader over a `geodrive build-dataset` manifest.jsonl, as the
// upstream GeoDrive training dataloader (train.py MyWebDataset): decode the GT
// and condition videos, pad each clip to `frames` by repeating its last frame
// (25 -> 49), resize as the pair's meta.json says (or as forced) to the model's
// pixel size, RGB float in [-1, 1]. Epoch order is a seeded shuffle; a worker
// thread decodes ahead into a bounded queue. Torch-free.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <mutex>
#include <opencv2/core.hpp>
#include <string>
#include <thread>
#include <vector>

#include "dataset/pairs.h"

namespace geodrive {
namespace diffusion {

struct PairsLoaderOptions {
  std::string manifest;  // OUT/manifest.jsonl
  int frames = 49;       // clip length after padding (longer clips: first N)
  int width = 720, height = 480;  // output pixel size
  // "pair" = the pair's meta.json resize_mode; or force "resize" (plain,
  // aspect-distorting, as upstream training) / "center-crop" (cover, then crop
  // the centre, as upstream inference).
  std::string resize_mode = "pair";
  bool shuffle = true;
  uint64_t seed = 0;
  int prefetch = 4;  // queue capacity (decoded samples held ahead)
  // Position in the endless sample stream (epoch e = samples [e*N, (e+1)*N)):
  // the first sample delivered, and how many (-1 = endless).
  int64_t start_sample = 0;
  int64_t num_samples = -1;
  void Check() const;
};

// One decoded pair.
struct PairSample {
  std::string clip_id;
  int64_t sample = 0;      // position in the sample stream
  int64_t pair_index = 0;  // index into the manifest
  int source_frames = 0;   // frames in the pair's videos before padding
  // `frames` RGB frames each, CV_32FC3, height x width, values in [-1, 1].
  std::vector<cv::Mat> gt, cond;
};

// The manifest order of epoch `epoch`: identity, or a permutation that is a
// pure function of (n, seed, epoch) (std::mt19937_64 Fisher-Yates, so it is the
// same on every platform).
std::vector<int64_t> EpochOrder(int64_t n,
                                uint64_t seed,
                                int64_t epoch,
                                bool shuffle);

// Pads (repeat last) or truncates `frames` to `count`; resizes each frame with
// `mode` ("resize" | "center-crop") to width x height; converts RGB CV_8UC3 to
// CV_32FC3 in [-1, 1] (x / 127.5 - 1). Throws InputError naming `what` when
// there are no frames.
std::vector<cv::Mat> PrepareClip(const std::vector<cv::Mat>& frames,
                                 int count,
                                 int width,
                                 int height,
                                 const std::string& mode,
                                 const std::string& what);

// Decodes one pair (record from ReadPair) with the loader's options.
PairSample LoadPairSample(const PairRecord& record,
                          const PairsLoaderOptions& options);

class PairsLoader {
 public:
  // Reads the manifest and every meta.json (throws InputError on bad input,
  // an empty manifest included), then starts the worker thread.
  explicit PairsLoader(const PairsLoaderOptions& options);
  ~PairsLoader();  // stops and joins the worker
  PairsLoader(const PairsLoader&) = delete;
  PairsLoader& operator=(const PairsLoader&) = delete;

  int64_t size() const { return static_cast<int64_t>(records_.size()); }
  const std::vector<PairRecord>& records() const { return records_; }
  // The next sample in stream order; false once num_samples were delivered.
  // Rethrows an error of the worker (e.g. an undecodable video) here.
  bool Next(PairSample* sample);
  // Largest queue length seen (tests: the bound holds).
  int max_queued() const;

 private:
  void Work();

  PairsLoaderOptions options_;
  std::vector<PairRecord> records_;
  std::thread worker_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<PairSample> queue_;
  std::exception_ptr error_;
  bool done_ = false, stop_ = false;
  int64_t delivered_ = 0;
  int max_queued_ = 0;
};

}  // namespace diffusion
}  // namespace geodrive
