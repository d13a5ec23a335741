#pragma once
// LPIPS, FID and FVD need learned networks (pytorch-fid Inception, I3D, LPIPS
// AlexNet) run as TorchScript models through LibTorch. They are compiled only
// with GEODRIVE_WITH_TORCH=ON:
//  - eval/deep_metrics_stub.cc (#ifndef GEODRIVE_WITH_TORCH): every entry point
//  reports that the
//    build has no LibTorch;
//  - eval/deep_metrics_torch.cc (#ifdef GEODRIVE_WITH_TORCH, to be written):
//  loads the models with
//    torch::jit::load and implements FeatureExtractor / LpipsModel with the
//    preprocessing of docs/EVAL.md. The Fréchet distance itself
//    (eval/frechet.h) needs no LibTorch.

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
  kInceptionFid,  // pytorch-fid Inception v3, 2048-d pool features, 299x299
                  // bilinear, [-1, 1]
  kI3dFvd,  // i3d_torchscript.pt, 400-d, common_metrics preprocessing (224
            // crop, [-1, 1])
};

// Features of RGB uint8 frames (FID: one row per frame; FVD: one row per clip
// of frames).
class FeatureExtractor {
 public:
  virtual ~FeatureExtractor() = default;
  // N x D features (float64) of `clips` (each a list of RGB CV_8UC3 frames).
  virtual Eigen::MatrixXd Extract(
      const std::vector<std::vector<cv::Mat>>& clips) = 0;
  virtual int dims() const = 0;
};

// LPIPS distance of frame pairs.
class LpipsModel {
 public:
  virtual ~LpipsModel() = default;
  // Mean LPIPS over the frames of one video pair (RGB CV_8UC3, same sizes).
  virtual double Distance(const cv::Mat& a, const cv::Mat& b) = 0;
};

// Load a user-provided TorchScript model. Without LibTorch they throw
// InputError carrying DeepMetricsUnavailableMessage(); with it, InputError for
// files that are not TorchScript models.
std::unique_ptr<FeatureExtractor> LoadFeatureExtractor(
    const std::string& model_path, FeatureNetwork network);
std::unique_ptr<LpipsModel> LoadLpipsModel(const std::string& model_path);

}  // namespace geodrive
