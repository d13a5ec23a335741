#pragma once
// The interface between eval/deep_metrics.cc and the LibTorch plugin
// libgeodrive-deep-metrics.so (eval/deep_metrics_torch.cc). Not installed.

#include <string>

#include "eval/deep_metrics.h"

namespace geodrive {

// What the plugin hands over. Each loader returns an object the caller owns
// (delete through the interface's virtual destructor) or throws InputError.
struct DeepMetricsPluginInfo {
  // The plugin's GEODRIVE_VERSION; must equal the loader's.
  const char* version = nullptr;
  FeatureExtractor* (*load_feature_extractor)(const std::string& model_path,
                                              FeatureNetwork network) = nullptr;
  LpipsModel* (*load_lpips_model)(const std::string& model_path) = nullptr;
};

constexpr char kDeepMetricsPluginFile[] = "libgeodrive-deep-metrics.so";
constexpr char kDeepMetricsPluginEntry[] = "GeodriveDeepMetricsPlugin";
using DeepMetricsPluginEntry = DeepMetricsPluginInfo (*)();

}  // namespace geodrive

#define GEODRIVE_DEEP_METRICS_PLUGIN_ENTRY(load_features, load_lpips)          \
  extern "C"                                                                   \
      __attribute__((visibility("default"))) ::geodrive::DeepMetricsPluginInfo \
      GeodriveDeepMetricsPlugin() {                                            \
    return {GEODRIVE_VERSION, load_features, load_lpips};                      \
  }
