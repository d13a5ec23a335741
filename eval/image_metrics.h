#pragma once
// Full-reference image metrics with the conventions papers use (docs/EVAL.md).
//
// PSNR: 10 log10(R^2 / MSE), MSE over every pixel and channel in float64, R =
// data_range (255 for 8-bit frames). Identical images (MSE/R^2 < 1e-10) give
// `max_db` instead of +inf. Same number as
// skimage.metrics.peak_signal_noise_ratio(gt, pred, data_range=R) and as
// common_metrics_on_video_quality on [0, 1] frames (R = 1 after dividing by
// 255).
//
// SSIM: Wang et al. 2004 -- Gaussian window (sigma 1.5, truncated at 3.5 sigma:
// 11x11), population covariance, C1 = (0.01 R)^2, C2 = (0.03 R)^2, SSIM map
// cropped by the window radius ("valid"), mean per channel in float64, then the
// mean over channels. Same number as
//   skimage.metrics.structural_similarity(gt, pred, gaussian_weights=True,
//   sigma=1.5,
//       use_sample_covariance=False, data_range=R, channel_axis=-1)
// (tested to 1e-10 against Debian's python3-skimage 0.19).
//
// Images are cv::Mat of the same size and type: CV_8UC1, CV_8UC3, CV_64FC1 or
// CV_64FC3. Channel order does not matter for the RGB variants (they are
// channel means); the luma variant needs RGB.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace geodrive {

struct PsnrOptions {
  // Peak value R of the signal (255 for uint8 frames, 1 for [0, 1] floats).
  double data_range = 255.0;
  // Returned when the images are identical (MSE / R^2 < 1e-10), as
  // common_metrics does.
  double max_db = 100.0;
  void Check() const;
};

struct SsimOptions {
  // Peak value R of the signal; C1 = (k1 R)^2, C2 = (k2 R)^2.
  double data_range = 255.0;
  // Gaussian window: radius = int(truncate * sigma + 0.5) as scipy.ndimage (5
  // -> 11x11).
  double sigma = 1.5;
  double truncate = 3.5;
  double k1 = 0.01;
  double k2 = 0.03;
  // The 11x11 window (radius 5) runs a fused single-pass kernel; false forces
  // the generic path (five cv::sepFilter2D maps as skimage computes them;
  // slower, kept as a cross-check).
  bool fused_kernel = true;
  void Check() const;
  // Radius of the window in pixels (5 for the defaults).
  int Radius() const;
};

// Mean squared error over all pixels and channels (float64).
double MeanSquaredError(const cv::Mat& a, const cv::Mat& b);
// PSNR in dB between two images (`what` names them in errors).
double Psnr(const cv::Mat& a,
            const cv::Mat& b,
            const PsnrOptions& options = {},
            const std::string& what = "images");

// SSIM per channel (one value per channel).
std::vector<double> SsimPerChannel(const cv::Mat& a,
                                   const cv::Mat& b,
                                   const SsimOptions& options = {},
                                   const std::string& what = "images");
// SSIM averaged over channels (skimage's channel_axis=-1 result).
double Ssim(const cv::Mat& a,
            const cv::Mat& b,
            const SsimOptions& options = {},
            const std::string& what = "images");

// Full-range BT.601 luma of an RGB image: Y = 0.299 R + 0.587 G + 0.114 B,
// float64, same range as the input (no rounding, no studio-range offset). `rgb`
// is CV_8UC3 or CV_64FC3 in RGB order.
cv::Mat LumaBt601(const cv::Mat& rgb);

// Which metrics to compute per frame.
struct FrameMetricsOptions {
  bool psnr = true;
  bool ssim = true;
  // Also the BT.601 luma variants (psnr_y, ssim_y).
  bool luma = false;
  PsnrOptions psnr_options;
  SsimOptions ssim_options;
  // Frames scored in parallel (OpenMP); 0 = OpenMP's default, 1 = this thread
  // only.
  int num_threads = 0;
  void Check() const;
};

// Scores of one frame pair; metrics not requested are NaN.
struct FrameScores {
  double psnr_rgb = 0;  // over all channels
  double ssim_rgb = 0;  // mean over channels
  double psnr_y = 0;    // BT.601 luma
  double ssim_y = 0;
};

// Scores of one video pair: per frame, and per video = the mean over frames
// (common_metrics).
struct VideoScores {
  std::vector<FrameScores> frames;
  FrameScores mean;
  int width = 0;
  int height = 0;
  std::string BriefReport() const;
};

// Compares `pred` with `gt` frame by frame. Throws InputError (naming `what`)
// for empty videos, different frame counts, sizes or types. `first_frame` is
// the index of pred[0] in its video (for messages, when a long video is
// compared a chunk at a time).
VideoScores CompareVideos(const std::vector<cv::Mat>& pred,
                          const std::vector<cv::Mat>& gt,
                          const FrameMetricsOptions& options = {},
                          const std::string& what = "video",
                          int64_t first_frame = 0);

// The per-video mean of `frames` as CompareVideos computes it (the same sums
// in the same order, so chunked comparisons give the same figures).
FrameScores MeanOfFrames(const std::vector<FrameScores>& frames);

}  // namespace geodrive
