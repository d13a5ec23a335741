// Deep metrics with LibTorch: user-provided TorchScript models (pytorch-fid
// Inception, I3D, LPIPS) and the preprocessing of docs/EVAL.md, done with
// LibTorch's own kernels (at::upsample_bilinear2d is what PyTorch's
// F.interpolate(mode='bilinear', align_corners=False) runs).
//
// Compiled only into the plugin libgeodrive-deep-metrics.so
// (eval/CMakeLists.txt), loaded by eval/deep_metrics.cc when a deep metric is
// asked for: no other binary links LibTorch (it costs 0.6 s of
// start-up per process).

#include <torch/script.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "eval/deep_metrics.h"
#include "eval/deep_metrics_plugin.h"
#include "geodrive_version.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

constexpr int kFidSize = 299;
constexpr int kFvdSize = 224;
// Frames per forward call of the FID network (a batch of 299x299 frames).
constexpr int kFidBatch = 8;

// First line of a (multi-line) LibTorch error, shortened: InputError messages
// are one line.
std::string FirstLine(const std::string& text) {
  std::string line = text.substr(0, text.find('\n'));
  if (line.size() > 300) line = line.substr(0, 300) + "...";
  return line;
}

std::string ShapeString(const at::Tensor& t) {
  std::ostringstream os;
  os << "[";
  for (int64_t i = 0; i < t.dim(); ++i) os << (i ? ", " : "") << t.size(i);
  os << "]";
  return os.str();
}

torch::jit::Module LoadModule(const std::string& path) {
  GEODRIVE_CHECK_INPUT(std::filesystem::is_regular_file(path), path,
                       ": not a TorchScript model: no such file");
  torch::jit::Module module;
  try {
    module = torch::jit::load(path, torch::kCPU);
  } catch (const std::exception& e) {
    ThrowInputError(path, "not a TorchScript model: ", FirstLine(e.what()));
  }
  GEODRIVE_CHECK_INPUT(module.find_method("forward").has_value(), path,
                       ": not a TorchScript model: it has no forward()");
  module.eval();
  return module;
}

// RGB CV_8UC3 frame -> float32 [3, H, W] in [0, 1] (torchvision ToTensor).
at::Tensor FrameToTensor(const cv::Mat& frame, const std::string& what) {
  GEODRIVE_CHECK_INPUT(!frame.empty() && frame.type() == CV_8UC3, what,
                       ": frames must be non-empty RGB uint8 (CV_8UC3)");
  const cv::Mat contiguous = frame.isContinuous() ? frame : frame.clone();
  return torch::from_blob(contiguous.data, {frame.rows, frame.cols, 3},
                          torch::kUInt8)
      .permute({2, 0, 1})
      .to(torch::kFloat32)
      .div(255.0);
}

// The output of a forward call as one tensor: a tensor, or the first tensor
// of a tuple/list (pytorch-fid's InceptionV3 returns a list of blocks).
at::Tensor OutputTensor(const c10::IValue& out, const std::string& path) {
  if (out.isTensor()) return out.toTensor();
  if (out.isTuple() && !out.toTupleRef().elements().empty() &&
      out.toTupleRef().elements()[0].isTensor()) {
    return out.toTupleRef().elements()[0].toTensor();
  }
  if (out.isTensorList() && out.toTensorList().size() > 0) {
    return out.toTensorList().get(0);
  }
  if (out.isList() && out.toListRef().size() > 0 &&
      out.toListRef()[0].isTensor()) {
    return out.toListRef()[0].toTensor();
  }
  ThrowInputError(path, "model output is ", out.tagKind(),
                  ", expected a tensor");
}

c10::IValue Forward(torch::jit::Module& module,
                    const std::string& path,
                    std::vector<c10::IValue> inputs,
                    const torch::jit::Kwargs& kwargs = {}) {
  try {
    return module.forward(std::move(inputs), kwargs);
  } catch (const std::exception& e) {  // c10::Error, torch::jit::JITException
    ThrowInputError(path, "model forward failed: ", FirstLine(e.what()));
  }
}

class TorchFeatureExtractor : public FeatureExtractor {
 public:
  TorchFeatureExtractor(std::string path, FeatureNetwork network)
      : path_(std::move(path)), network_(network), module_(LoadModule(path_)) {
    if (network_ == FeatureNetwork::kI3dFvd) {
      // i3d_torchscript.pt: forward(x, rescale, resize, return_features);
      // common_metrics calls it with rescale=False, resize=False,
      // return_features=True. Models without these arguments get x alone.
      const c10::FunctionSchema& schema =
          module_.get_method("forward").function().getSchema();
      for (const c10::Argument& arg : schema.arguments()) {
        if (arg.name() == "rescale" || arg.name() == "resize") {
          kwargs_[arg.name()] = false;
        } else if (arg.name() == "return_features") {
          kwargs_[arg.name()] = true;
        }
      }
    }
  }

  Eigen::MatrixXd Extract(
      const std::vector<std::vector<cv::Mat>>& clips) override {
    torch::NoGradGuard no_grad;
    std::vector<at::Tensor> rows;
    if (network_ == FeatureNetwork::kInceptionFid) {
      std::vector<at::Tensor> batch;
      auto flush = [&] {
        if (batch.empty()) return;
        rows.push_back(Run({torch::cat(batch, 0)}, batch.size()));
        batch.clear();
      };
      for (const auto& clip : clips) {
        for (const cv::Mat& frame : clip) {
          batch.push_back(PreprocessFid(FrameToTensor(frame, path_)));
          if (static_cast<int>(batch.size()) == kFidBatch) flush();
        }
      }
      flush();
    } else {
      for (const auto& clip : clips) {
        GEODRIVE_CHECK_INPUT(!clip.empty(), path_,
                             ": FVD needs clips with frames (got an empty "
                             "clip)");
        rows.push_back(Run({PreprocessFvd(clip)}, 1));
      }
    }
    GEODRIVE_CHECK_INPUT(!rows.empty(), path_, ": no frames to extract from");
    const at::Tensor all = torch::cat(rows, 0).contiguous();
    Eigen::MatrixXd out(all.size(0), all.size(1));
    const auto acc = all.accessor<double, 2>();
    for (int64_t i = 0; i < all.size(0); ++i) {
      for (int64_t j = 0; j < all.size(1); ++j) out(i, j) = acc[i][j];
    }
    GEODRIVE_CHECK_INPUT(out.allFinite(), path_,
                         ": model returned non-finite features");
    return out;
  }

  int dims() const override { return dims_; }

 private:
  // [3, H, W] in [0, 1] -> [1, 3, 299, 299] in [-1, 1] (pytorch-fid
  // InceptionV3(resize_input=True, normalize_input=True) order: resize, then
  // 2x - 1).
  static at::Tensor PreprocessFid(const at::Tensor& frame) {
    const at::Tensor resized =
        at::upsample_bilinear2d(frame.unsqueeze(0), {kFidSize, kFidSize},
                                /*align_corners=*/false);
    return resized * 2 - 1;
  }

  // Frames -> [1, 3, T, 224, 224] in [-1, 1], as common_metrics'
  // preprocess_single on a [C, T, H, W] video in [0, 1].
  at::Tensor PreprocessFvd(const std::vector<cv::Mat>& clip) const {
    std::vector<at::Tensor> frames;
    for (const cv::Mat& f : clip) {
      GEODRIVE_CHECK_INPUT(f.size() == clip[0].size(), path_,
                           ": frames of one clip differ in size");
      frames.push_back(FrameToTensor(f, path_));
    }
    const at::Tensor video = torch::stack(frames, 1);  // [3, T, H, W]
    const int64_t h = video.size(2), w = video.size(3);
    const double scale = static_cast<double>(kFvdSize) / std::min(h, w);
    const int64_t th = h < w ? kFvdSize : std::ceil(h * scale);
    const int64_t tw = h < w ? std::ceil(w * scale) : kFvdSize;
    // F.interpolate on the 4-D [C, T, H, W] tensor: every (c, t) plane alone.
    at::Tensor resized =
        at::upsample_bilinear2d(video, {th, tw}, /*align_corners=*/false);
    const int64_t h0 = (th - kFvdSize) / 2, w0 = (tw - kFvdSize) / 2;
    resized = resized.slice(2, h0, h0 + kFvdSize).slice(3, w0, w0 + kFvdSize);
    return ((resized - 0.5) * 2).contiguous().unsqueeze(0);
  }

  // Runs the model on one batch of `n` inputs; returns [n, D] float64.
  at::Tensor Run(std::vector<c10::IValue> inputs, size_t n) {
    const at::Tensor raw = OutputTensor(
        Forward(module_, path_, std::move(inputs), kwargs_), path_);
    // [n, D] or [n, D, 1, 1, ...] (pytorch-fid's pool block is [n, 2048, 1,
    // 1]).
    bool ok = raw.dim() >= 2 && raw.size(0) == static_cast<int64_t>(n) &&
              raw.size(1) > 0;
    for (int64_t i = 2; ok && i < raw.dim(); ++i) ok = raw.size(i) == 1;
    if (ok && dims_ > 0) ok = raw.size(1) == dims_;
    GEODRIVE_CHECK_INPUT(
        ok, path_, ": model output has shape ", ShapeString(raw),
        ", expected [", n, ", D] (or [", n, ", D, 1, 1]) for ", n, " input",
        n == 1 ? "" : "s",
        dims_ > 0 ? " with D = " + std::to_string(dims_) : std::string());
    GEODRIVE_CHECK_INPUT(raw.is_floating_point(), path_,
                         ": model output is not floating point");
    dims_ = static_cast<int>(raw.size(1));
    return raw.reshape({raw.size(0), raw.size(1)}).to(torch::kFloat64);
  }

  std::string path_;
  FeatureNetwork network_;
  torch::jit::Module module_;
  torch::jit::Kwargs kwargs_;
  int dims_ = 0;
};

class TorchLpipsModel : public LpipsModel {
 public:
  explicit TorchLpipsModel(std::string path)
      : path_(std::move(path)), module_(LoadModule(path_)) {}

  double Distance(const cv::Mat& a, const cv::Mat& b) override {
    torch::NoGradGuard no_grad;
    GEODRIVE_CHECK_INPUT(a.size() == b.size(), path_,
                         ": LPIPS frames differ in size (", a.cols, "x", a.rows,
                         " vs ", b.cols, "x", b.rows, ")");
    // LPIPS takes [-1, 1] (lpips.LPIPS(...)(x, y, normalize=False)).
    const at::Tensor x = FrameToTensor(a, path_).unsqueeze(0) * 2 - 1;
    const at::Tensor y = FrameToTensor(b, path_).unsqueeze(0) * 2 - 1;
    const at::Tensor raw = OutputTensor(Forward(module_, path_, {x, y}), path_);
    GEODRIVE_CHECK_INPUT(
        raw.dim() == 4 && raw.size(0) == 1 && raw.size(1) == 1 &&
            raw.numel() > 0 && raw.is_floating_point(),
        path_, ": model output has shape ", ShapeString(raw),
        ", expected [1, 1, 1, 1] (or a [1, 1, h, w] spatial map) for one "
        "frame pair");
    const double d = raw.to(torch::kFloat64).mean().item<double>();
    GEODRIVE_CHECK_INPUT(std::isfinite(d), path_,
                         ": model returned a non-finite distance");
    return d;
  }

 private:
  std::string path_;
  torch::jit::Module module_;
};

}  // namespace

// The plugin's loaders (eval/deep_metrics.h says what they check).
FeatureExtractor* TorchLoadFeatureExtractor(const std::string& model_path,
                                            FeatureNetwork network) {
  GEODRIVE_CHECK_INPUT(!model_path.empty(),
                       network == FeatureNetwork::kInceptionFid
                           ? "fid needs an Inception TorchScript model path"
                           : "fvd needs an I3D TorchScript model path");
  return new TorchFeatureExtractor(model_path, network);
}

LpipsModel* TorchLoadLpipsModel(const std::string& model_path) {
  GEODRIVE_CHECK_INPUT(!model_path.empty(),
                       "lpips needs an LPIPS TorchScript model path");
  return new TorchLpipsModel(model_path);
}

}  // namespace geodrive

GEODRIVE_DEEP_METRICS_PLUGIN_ENTRY(::geodrive::TorchLoadFeatureExtractor,
                                   ::geodrive::TorchLoadLpipsModel)
