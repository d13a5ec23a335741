// Deep metrics through the LibTorch plugin (eval/deep_metrics_plugin.h),
// loaded the first time a model is loaded. A build without LibTorch has no
// plugin: every entry point then explains what is missing.

#include "eval/deep_metrics.h"

#include <mutex>
#include <stdexcept>

#include "eval/deep_metrics_plugin.h"
#include "geodrive_version.h"
#include "geometry/util/plugin.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// The plugin's loaders, or throws InputError naming `what` and why there is
// none (no plugin in this build, or one that cannot be loaded).
const DeepMetricsPluginInfo& Plugin(const std::string& what) {
  static std::once_flag once;
  static DeepMetricsPluginInfo info;
  static std::string error;
  std::call_once(once, [] {
    if (FindPlugin(kDeepMetricsPluginFile).empty()) {
      error = DeepMetricsUnavailableMessage();
      return;
    }
    try {
      const auto entry = reinterpret_cast<DeepMetricsPluginEntry>(
          LoadPluginSymbol(kDeepMetricsPluginFile, kDeepMetricsPluginEntry));
      DeepMetricsPluginInfo loaded = entry();
      if (loaded.version == nullptr ||
          std::string(loaded.version) != GEODRIVE_VERSION ||
          loaded.load_feature_extractor == nullptr ||
          loaded.load_lpips_model == nullptr) {
        error = std::string(kDeepMetricsPluginFile) + " is version " +
                (loaded.version ? loaded.version : "?") + ", this program " +
                GEODRIVE_VERSION;
        return;
      }
      info = loaded;
    } catch (const std::runtime_error& e) {
      error = e.what();
    }
  });
  if (!error.empty()) ThrowInputError(what, error);
  return info;
}

}  // namespace

bool DeepMetricsAvailable() {
  return !FindPlugin(kDeepMetricsPluginFile).empty();
}

std::string DeepMetricsUnavailableMessage() {
  return "lpips/fid/fvd need a build with GEODRIVE_WITH_TORCH=ON and a "
         "TorchScript model (no " +
         std::string(kDeepMetricsPluginFile) +
         " found; psnr, ssim, ade and fde work without it)";
}

std::unique_ptr<FeatureExtractor> LoadFeatureExtractor(
    const std::string& model_path, FeatureNetwork network) {
  const auto& plugin = Plugin(
      model_path.empty() ? std::string("feature extractor") : model_path);
  return std::unique_ptr<FeatureExtractor>(
      plugin.load_feature_extractor(model_path, network));
}

std::unique_ptr<LpipsModel> LoadLpipsModel(const std::string& model_path) {
  const auto& plugin =
      Plugin(model_path.empty() ? std::string("lpips model") : model_path);
  return std::unique_ptr<LpipsModel>(plugin.load_lpips_model(model_path));
}

}  // namespace geodrive
