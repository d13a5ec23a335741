// Deep metrics in a build without LibTorch: every entry point explains what is
// missing.
#ifndef GEODRIVE_WITH_TORCH

#include "eval/deep_metrics.h"
#include "geometry/util/status.h"

namespace geodrive {

bool DeepMetricsAvailable() { return false; }

std::string DeepMetricsUnavailableMessage() {
  return "lpips/fid/fvd need a build with GEODRIVE_WITH_TORCH=ON and a "
         "TorchScript model "
         "(this build has no LibTorch; psnr, ssim, ade and fde work without "
         "it)";
}

std::unique_ptr<FeatureExtractor> LoadFeatureExtractor(
    const std::string& model_path, FeatureNetwork /*network*/) {
  ThrowInputError(
      model_path.empty() ? std::string("feature extractor") : model_path,
      DeepMetricsUnavailableMessage());
}

std::unique_ptr<LpipsModel> LoadLpipsModel(const std::string& model_path) {
  ThrowInputError(model_path.empty() ? std::string("lpips model") : model_path,
                  DeepMetricsUnavailableMessage());
}

}  // namespace geodrive

#endif  // GEODRIVE_WITH_TORCH
