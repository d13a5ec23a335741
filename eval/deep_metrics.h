#pragma once
// LPIPS, FID and FVD need learned networks (pytorch-fid Inception, I3D, LPIPS
// AlexNet) that the user provides as TorchScript models, run through LibTorch
// (docs/EVAL.md says what each model must be and how it is preprocessed):
//  - eval/deep_metrics_torch.cc: torch::jit::load and the documented
//    preprocessing, done with LibTorch's own kernels, built (with
//    GEODRIVE_WITH_TORCH=ON) as the plugin libgeodrive-deep-metrics.so;
//  - eval/deep_metrics.cc: these entry points, which load that plugin on first
//    use (geometry/util/plugin.h), so that no binary links LibTorch; without
//    the plugin they report that the build has no LibTorch.
// The Fréchet distance itself (eval/frechet.h) needs no LibTorch.

#include <Eigen/Core>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace geodrive {

// True when this build can run TorchScript models (GEODRIVE_WITH_TORCH=ON).
bool DeepMetricsAvailable();
// The message printed when a deep metric is requested from a build without
// LibTorch.
std::string DeepMetricsUnavailableMessage();

enum class FeatureNetwork {
  // pytorch-fid Inception v3 pool features (2048-d): each frame /255, bilinear
  // 299x299 (align_corners=False, no antialias), 2x - 1; input [N,3,299,299].
  kInceptionFid,
  // i3d_torchscript.pt logits (400-d), common_metrics_on_video_quality: clip
  // /255, shorter side bilinear to 224 (longer side ceil), centre crop
  // 224x224, 2x - 1; input [N,3,T,224,224], called with rescale=False,
  // resize=False, return_features=True when forward() has those arguments.
  kI3dFvd,
};

// Features of RGB uint8 frames (FID: one row per frame; FVD: one row per clip
// of frames).
class FeatureExtractor {
 public:
  virtual ~FeatureExtractor() = default;
  // Features (float64) of `clips` (each a list of RGB CV_8UC3 frames): FID
  // gives one row per frame of every clip, in order; FVD one row per clip.
  // Throws InputError for empty/non-RGB frames or a model output that is not
  // [N, D] (or [N, D, 1, ...]).
  virtual Eigen::MatrixXd Extract(
      const std::vector<std::vector<cv::Mat>>& clips) = 0;
  // Feature dimension D seen in the last Extract (0 before the first).
  virtual int dims() const = 0;
};

// LPIPS distance of frame pairs.
class LpipsModel {
 public:
  virtual ~LpipsModel() = default;
  // LPIPS of one frame pair (RGB CV_8UC3, same size): both /255 -> 2x - 1, no
  // resize, model(a, b); a [1,1,h,w] output is averaged over h, w (so both
  // spatial=False and spatial=True LPIPS models work).
  virtual double Distance(const cv::Mat& a, const cv::Mat& b) = 0;
};

// Load a user-provided TorchScript model (CPU). Without LibTorch they throw
// InputError carrying DeepMetricsUnavailableMessage(); with it, InputError
// ("<path>: not a TorchScript model: ...") for missing files and files that
// are not TorchScript models.
std::unique_ptr<FeatureExtractor> LoadFeatureExtractor(
    const std::string& model_path, FeatureNetwork network);
std::unique_ptr<LpipsModel> LoadLpipsModel(const std::string& model_path);

}  // namespace geodrive
