// LPIPS / FID / FVD through TorchScript models (built only with
// GEODRIVE_WITH_TORCH): small deterministic models that
// tests/eval/make_torchscript_models.py builds with Debian's python3-torch,
// features from C++ against the features PyTorch computes with the documented
// preprocessing (docs/EVAL.md), bad model files, and `geodrive eval`
// end to end.
#ifdef GEODRIVE_WITH_TORCH

#include "eval/deep_metrics.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "eval/frechet.h"
#include "geometry/npy.h"
#include "geometry/util/status.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace deep_metrics_test {
namespace {

namespace fs = std::filesystem;

// Absolute tolerance on features / distances: both sides run the same float32
// network on the same float32 inputs; only the batching (C++ runs FID frames
// in batches of 8, the reference one by one) and the order of float32
// reductions may differ, ~1e-7 relative on O(1) values.
constexpr double kTol = 1e-5;

// A random RGB clip (w x h, n frames): a colour gradient between two random
// colours plus blurred noise, drifting from frame to frame, brightened by
// `offset` grey levels.
std::vector<cv::Mat> MakeClip(
    int w, int h, int n, uint32_t seed, int offset = 0) {
  std::mt19937 rng(seed);
  cv::Mat noise(h, w, CV_8UC3);
  for (size_t k = 0; k < noise.total() * 3; ++k) noise.data[k] = rng() % 256;
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 1.2);
  int c0[3], c1[3];
  for (int ch = 0; ch < 3; ++ch) {
    c0[ch] = 30 + rng() % 196;
    c1[ch] = 30 + rng() % 196;
  }
  std::vector<cv::Mat> out;
  for (int i = 0; i < n; ++i) {
    cv::Mat f(h, w, CV_8UC3);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const double t = (x + 0.5 * y) / (w + 0.5 * h);
        for (int ch = 0; ch < 3; ++ch) {
          const int v = static_cast<int>(c0[ch] + t * (c1[ch] - c0[ch])) +
                        (noise.at<cv::Vec3b>(y, x)[ch] - 128) / 2 +
                        static_cast<int>(rng() % 21) - 10 + 3 * i + offset;
          f.at<cv::Vec3b>(y, x)[ch] =
              static_cast<uint8_t>(std::clamp(v, 0, 255));
        }
      }
    }
    out.push_back(f);
  }
  return out;
}

// The same clips, every pixel `delta` grey levels brighter (saturating).
std::vector<std::vector<cv::Mat>> Brighter(
    const std::vector<std::vector<cv::Mat>>& clips, int delta) {
  std::vector<std::vector<cv::Mat>> out;
  for (const auto& clip : clips) {
    out.emplace_back();
    for (const cv::Mat& f : clip)
      out.back().push_back(f + cv::Scalar::all(delta));
  }
  return out;
}

// The clips of each data set, by folder: <root>/frames/<set>/<clip>/*.png.
struct DataSet {
  std::string name;
  std::vector<std::vector<cv::Mat>> clips;
};

std::vector<DataSet> MakeDataSets() {
  std::vector<DataSet> sets;
  // FID: frames of different sizes and aspect ratios, pooled (13 frames: the
  // C++ batches of 8 end mid-clip).
  sets.push_back({"fid",
                  {MakeClip(64, 48, 5, 1), MakeClip(30, 70, 3, 2),
                   MakeClip(301, 17, 5, 3)}});
  // FVD: landscape (long side ceil(58 * 5.6) = 325), portrait, square clips.
  sets.push_back({"fvd",
                  {MakeClip(58, 40, 10, 4), MakeClip(40, 60, 10, 5),
                   MakeClip(32, 32, 12, 6)}});
  // LPIPS: frame pairs a/ b/ (3 pairs, 48x64).
  sets.push_back({"lpips", {MakeClip(64, 48, 3, 7), MakeClip(64, 48, 3, 8)}});
  // CLI: 6 predicted and 6 ground-truth videos of 10 frames (60 frames > 16
  // inception_like dims; 6 clips > 4 i3d_small dims).
  for (const char* side : {"cli_pred", "cli_gt"}) {
    DataSet set{side, {}};
    for (int c = 0; c < 6; ++c) {
      const bool pred = side[4] == 'p';
      set.clips.push_back(
          MakeClip(40, 32, 10, 100 + c + (pred ? 50 : 0), pred ? 30 : 0));
    }
    sets.push_back(set);
  }
  return sets;
}

std::string ClipName(const DataSet& set, size_t c) {
  if (set.name == "lpips") return c == 0 ? "a" : "b";
  return "clip_" + std::to_string(c);
}

// Models and Python features, built once per test binary. A failure of the
// Python side is recorded in python_failed.txt (the fixture must not throw).
std::string Fixture() {
  return test::SharedFixtureDir(
      "deep_metrics_torchscript", [](const std::string& dir) {
        for (const DataSet& set : MakeDataSets()) {
          for (size_t c = 0; c < set.clips.size(); ++c) {
            WriteVideoFrames(
                dir + "/frames/" + set.name + "/" + ClipName(set, c),
                set.clips[c]);
          }
        }
        fs::create_directories(dir + "/expected");
        std::string jobs;
        auto job = [&](const std::string& kind, const std::string& model,
                       const std::string& set, const std::string& out) {
          jobs += " " + kind + ":" + model + ":" + dir + "/frames/" + set +
                  ":" + dir + "/expected/" + out + ".npy";
        };
        job("fid", "inception_like", "fid", "fid");
        job("fvd", "i3d_like", "fvd", "fvd");
        job("lpips", "lpips_like", "lpips", "lpips");
        job("fid", "inception_like", "cli_pred", "cli_fid_pred");
        job("fid", "inception_like", "cli_gt", "cli_fid_gt");
        job("fvd", "i3d_small", "cli_pred", "cli_fvd_pred");
        job("fvd", "i3d_small", "cli_gt", "cli_fvd_gt");
        std::string out;
        const int rc =
            test::RunCommand(std::string(test::kDebianPython) +
                                 " " GEODRIVE_SOURCE_DIR
                                 "/tests/eval/make_torchscript_models.py " +
                                 dir + "/models" + jobs,
                             &out);
        if (rc != 0) std::ofstream(dir + "/python_failed.txt") << out;
      });
}

// The fixture, or a test failure when Python could not build it.
std::string FixtureOrFail() {
  const std::string dir = Fixture();
  std::ifstream failed(dir + "/python_failed.txt");
  if (failed.good()) {
    std::stringstream ss;
    ss << failed.rdbuf();
    ADD_FAILURE() << "make_torchscript_models.py failed:\n" << ss.str();
    return "";
  }
  return dir;
}

Eigen::MatrixXd ReadExpected(const std::string& path) {
  const NpyArray a = ReadNpy(path);
  EXPECT_EQ(a.dtype, NpyDtype::kFloat64) << path;
  const int64_t rows = a.shape.empty() ? 1 : a.shape[0];
  const int64_t cols = a.shape.size() < 2 ? 1 : a.shape[1];
  Eigen::MatrixXd m(rows, cols);
  for (int64_t i = 0; i < rows; ++i)
    for (int64_t j = 0; j < cols; ++j) m(i, j) = a.Data<double>()[i * cols + j];
  return m;
}

DataSet Set(const std::string& name) {
  for (DataSet& s : MakeDataSets())
    if (s.name == name) return s;
  return {};
}

TEST(DeepMetrics, FidFeaturesMatchPytorchFidPreprocessing) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  const std::string dir = FixtureOrFail();
  ASSERT_FALSE(dir.empty());
  auto net = LoadFeatureExtractor(dir + "/models/inception_like.pt",
                                  FeatureNetwork::kInceptionFid);
  EXPECT_EQ(net->dims(), 0);
  const Eigen::MatrixXd features = net->Extract(Set("fid").clips);
  const Eigen::MatrixXd expected = ReadExpected(dir + "/expected/fid.npy");
  ASSERT_EQ(features.rows(), 13);
  ASSERT_EQ(features.cols(), 16);
  EXPECT_EQ(net->dims(), 16);
  const double err = (features - expected).cwiseAbs().maxCoeff();
  std::cout << "FID features (13 frames x 16): max |C++ - Python| = " << err
            << ", feature scale " << expected.cwiseAbs().maxCoeff() << "\n";
  EXPECT_LE(err, kTol);
  // The comparison resolves far less than a preprocessing error: frames 2 grey
  // levels brighter move the features by > 100x the tolerance.
  const double moved = (net->Extract(Brighter(Set("fid").clips, 2)) - features)
                           .cwiseAbs()
                           .maxCoeff();
  std::cout << "  features move by " << moved << " for +2 grey levels\n";
  EXPECT_GT(moved, 100 * kTol);
  // Same inputs -> byte-identical features.
  EXPECT_TRUE(
      (net->Extract(Set("fid").clips).array() == features.array()).all());
}

TEST(DeepMetrics, FvdFeaturesMatchCommonMetricsPreprocessing) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  const std::string dir = FixtureOrFail();
  ASSERT_FALSE(dir.empty());
  auto net = LoadFeatureExtractor(dir + "/models/i3d_like.pt",
                                  FeatureNetwork::kI3dFvd);
  const Eigen::MatrixXd features = net->Extract(Set("fvd").clips);
  const Eigen::MatrixXd expected = ReadExpected(dir + "/expected/fvd.npy");
  ASSERT_EQ(features.rows(), 3);
  ASSERT_EQ(features.cols(), 400);
  const double err = (features - expected).cwiseAbs().maxCoeff();
  std::cout << "FVD features (3 clips x 400): max |C++ - Python| = " << err
            << ", feature scale " << expected.cwiseAbs().maxCoeff() << "\n";
  EXPECT_LE(err, kTol);
  const double moved = (net->Extract(Brighter(Set("fvd").clips, 2)) - features)
                           .cwiseAbs()
                           .maxCoeff();
  std::cout << "  features move by " << moved << " for +2 grey levels\n";
  EXPECT_GT(moved, 100 * kTol);
  // The model returns softmax probabilities (rows sum to 1) unless called with
  // return_features=True: these are the logits.
  EXPECT_GT(std::abs(features.row(0).sum() - 1.0), 0.1);
}

TEST(DeepMetrics, LpipsMatchesPython) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  const std::string dir = FixtureOrFail();
  ASSERT_FALSE(dir.empty());
  auto net = LoadLpipsModel(dir + "/models/lpips_like.pt");
  const DataSet set = Set("lpips");
  const Eigen::MatrixXd expected = ReadExpected(dir + "/expected/lpips.npy");
  ASSERT_EQ(expected.rows(), 3);
  double err = 0;
  for (int i = 0; i < 3; ++i) {
    const double d = net->Distance(set.clips[0][i], set.clips[1][i]);
    err = std::max(err, std::abs(d - expected(i, 0)));
    EXPECT_GT(d, 0.0);
    // Resolution: 2 grey levels on one side move the distance by > 100x kTol.
    EXPECT_GT(std::abs(net->Distance(set.clips[0][i] + cv::Scalar::all(2),
                                     set.clips[1][i]) -
                       d),
              100 * kTol);
    EXPECT_EQ(net->Distance(set.clips[0][i], set.clips[0][i]), 0.0);
  }
  std::cout << "LPIPS (3 pairs): max |C++ - Python| = " << err
            << ", distances ~" << expected(0, 0) << "\n";
  EXPECT_LE(err, kTol);
  EXPECT_THROW(net->Distance(set.clips[0][0], MakeClip(32, 32, 1, 9)[0]),
               InputError);
}

// Calls `fn`, expects an InputError whose message contains every `parts`.
template <typename Fn>
void ExpectInputError(Fn fn, const std::vector<std::string>& parts) {
  try {
    fn();
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    for (const std::string& p : parts)
      EXPECT_NE(what.find(p), std::string::npos) << what << " lacks " << p;
  }
}

TEST(DeepMetrics, FilesThatAreNotModelsAreInputErrors) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  const std::string dir = FixtureOrFail();
  ASSERT_FALSE(dir.empty());
  const std::string tmp = test::MakeTempDir("deep_metrics_bad");
  const std::string text = tmp + "/model.pt";
  std::ofstream(text) << "this is not a model\n";
  // A .pt (zip archive) cut in the middle.
  const std::string truncated = tmp + "/truncated.pt";
  {
    std::ifstream in(dir + "/models/inception_like.pt", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)),
                      std::istreambuf_iterator<char>());
    ASSERT_GT(bytes.size(), 1000u);
    std::ofstream(truncated, std::ios::binary)
        << bytes.substr(0, bytes.size() / 2);
  }
  for (const std::string& path : {text, truncated, tmp + "/missing.pt"}) {
    ExpectInputError(
        [&] { LoadFeatureExtractor(path, FeatureNetwork::kInceptionFid); },
        {path, "not a TorchScript model"});
    ExpectInputError([&] { LoadLpipsModel(path); },
                     {path, "not a TorchScript model"});
  }
}

TEST(DeepMetrics, WrongModelOutputsAreInputErrors) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  const std::string dir = FixtureOrFail();
  ASSERT_FALSE(dir.empty());
  const std::string bad = dir + "/models/bad_output.pt";
  auto fid = LoadFeatureExtractor(bad, FeatureNetwork::kInceptionFid);
  ExpectInputError([&] { fid->Extract(Set("fid").clips); },
                   {bad, "model output has shape [5]", "expected [8, D]"});
  // An LPIPS model called with one input, and an FID network given clips.
  auto lpips = LoadLpipsModel(dir + "/models/inception_like.pt");
  const auto frames = MakeClip(32, 32, 2, 11);
  ExpectInputError([&] { lpips->Distance(frames[0], frames[1]); },
                   {"inception_like.pt", "model forward failed"});
  auto fvd = LoadFeatureExtractor(dir + "/models/inception_like.pt",
                                  FeatureNetwork::kI3dFvd);
  ExpectInputError([&] { fvd->Extract({frames}); },
                   {"inception_like.pt", "model forward failed"});
  // Frames that are not RGB uint8.
  auto good = LoadFeatureExtractor(dir + "/models/inception_like.pt",
                                   FeatureNetwork::kInceptionFid);
  ExpectInputError([&] { good->Extract({{cv::Mat(8, 8, CV_32FC3)}}); },
                   {"RGB uint8"});
}

FeatureStatistics Stats(const std::string& path) {
  return ComputeFeatureStatistics(ReadExpected(path));
}

TEST(DeepMetrics, CliLpipsFidFvdAndReferenceStatsCache) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("torch");
  const std::string dir = FixtureOrFail();
  ASSERT_FALSE(dir.empty());
  const std::string tmp = test::MakeTempDir("deep_metrics_cli");
  const std::string models = dir + "/models/";
  const std::string common = " --pred " + dir + "/frames/cli_pred --gt " + dir +
                             "/frames/cli_gt --lpips-model " + models +
                             "lpips_like.pt" + " --fid-model " + models +
                             "inception_like.pt --fvd-model " + models +
                             "i3d_small.pt";
  int rc = 0;
  std::string out = test::RunGeodriveEval(
      "--metrics psnr,lpips,fid,fvd --fid-stats " + tmp +
          "/stats/ref_fid --fvd-stats " + tmp + "/stats/ref_fvd --out " + tmp +
          "/a/report.json" + common,
      &rc);
  ASSERT_EQ(rc, 0) << out;
  std::ifstream in(tmp + "/a/report.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  // Reference: Fréchet distance of the Python features.
  const std::string e = dir + "/expected/";
  const double fid = FrechetDistance(Stats(e + "cli_fid_pred.npy"),
                                     Stats(e + "cli_fid_gt.npy"))
                         .distance;
  const double fvd = FrechetDistance(Stats(e + "cli_fvd_pred.npy"),
                                     Stats(e + "cli_fvd_gt.npy"))
                         .distance;
  // LPIPS reference: the library (checked against Python above).
  auto lpips_net = LoadLpipsModel(models + "lpips_like.pt");
  double lpips = 0;
  for (int c = 0; c < 6; ++c) {
    const auto pred =
        ReadVideoFrames(dir + "/frames/cli_pred/clip_" + std::to_string(c));
    const auto gt =
        ReadVideoFrames(dir + "/frames/cli_gt/clip_" + std::to_string(c));
    double sum = 0;
    for (size_t i = 0; i < pred.size(); ++i)
      sum += lpips_net->Distance(pred[i], gt[i]);
    lpips += sum / pred.size() / 6;
  }
  const nlohmann::json& s = j["summary"];
  std::cout << "CLI: fid " << s["fid"]["value"] << " (Python features " << fid
            << "), fvd " << s["fvd"]["value"] << " (" << fvd << "), lpips "
            << s["lpips"]["mean"] << " (" << lpips << ")\n";
  // Features agree to 1e-5 (absolute, on features of magnitude ~1-10); the
  // distances are sums of D..D^2 products of them: 1e-5 relative. The
  // prediction is 30 grey levels brighter, so the distances are far from 0.
  EXPECT_GT(fid, 1.0);
  EXPECT_GT(fvd, 0.01);
  EXPECT_NEAR(s["fid"]["value"].get<double>(), fid, 1e-5 * fid);
  EXPECT_NEAR(s["fvd"]["value"].get<double>(), fvd, 1e-5 * fvd);
  EXPECT_NEAR(s["lpips"]["mean"].get<double>(), lpips, 1e-9);
  EXPECT_EQ(s["fid"]["pred_samples"].get<int>(), 60);
  EXPECT_EQ(s["fid"]["gt_samples"].get<int>(), 60);
  EXPECT_EQ(s["fvd"]["pred_samples"].get<int>(), 6);
  EXPECT_EQ(j["videos"][0]["lpips_per_frame"].size(), 10u);
  EXPECT_TRUE(fs::exists(tmp + "/stats/ref_fid_mu.npy"));
  EXPECT_TRUE(fs::exists(tmp + "/stats/ref_fvd_sigma.npy"));
  std::ifstream md(tmp + "/a/report.md");
  std::string table;
  std::getline(md, table);
  std::getline(md, table);
  std::getline(md, table);
  EXPECT_EQ(table.rfind("| ours | ", 0), 0u) << table;
  EXPECT_EQ(table.find("| - | - | - | - |"), std::string::npos) << table;

  // Second run: the cached reference statistics replace --gt for fid/fvd.
  out = test::RunGeodriveEval(
      "--metrics fid,fvd --pred " + dir + "/frames/cli_pred --fid-model " +
          models + "inception_like.pt --fvd-model " + models +
          "i3d_small.pt --fid-stats " + tmp + "/stats/ref_fid --fvd-stats " +
          tmp + "/stats/ref_fvd --out " + tmp + "/b/report.json",
      &rc);
  ASSERT_EQ(rc, 0) << out;
  std::ifstream in2(tmp + "/b/report.json");
  const nlohmann::json j2 = nlohmann::json::parse(in2);
  // Cached statistics: no ground-truth sample count (null, not a sentinel).
  EXPECT_TRUE(j2["summary"]["fid"]["gt_samples"].is_null());
  EXPECT_EQ(j2["summary"]["fid"]["gt_stats"].get<std::string>(),
            tmp + "/stats/ref_fid");
  EXPECT_NEAR(j2["summary"]["fid"]["value"].get<double>(),
              s["fid"]["value"].get<double>(), 1e-9);
  EXPECT_NEAR(j2["summary"]["fvd"]["value"].get<double>(),
              s["fvd"]["value"].get<double>(), 1e-9);

  // Bad input: reference statistics of another model (4-d FVD statistics
  // given as 16-d FID statistics), a model flag missing, a non-model file.
  out = test::RunGeodriveEval("--metrics fid --pred " + dir +
                                  "/frames/cli_pred --fid-model " + models +
                                  "inception_like.pt --fid-stats " + tmp +
                                  "/stats/ref_fvd --out " + tmp + "/c.json",
                              &rc);
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("reference statistics have 4 dimensions, the fid model "
                     "gives 16"),
            std::string::npos)
      << out;
  out = test::RunGeodriveEval("--metrics fid --pred " + dir +
                                  "/frames/cli_pred --gt " + dir +
                                  "/frames/cli_gt --out " + tmp + "/c.json",
                              &rc);
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("--metrics fid needs --fid-model"), std::string::npos)
      << out;
  std::ofstream(tmp + "/text.pt") << "not a model";
  out = test::RunGeodriveEval("--metrics lpips --pred " + dir +
                                  "/frames/cli_pred --gt " + dir +
                                  "/frames/cli_gt --lpips-model " + tmp +
                                  "/text.pt --out " + tmp + "/c.json",
                              &rc);
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find(tmp + "/text.pt: not a TorchScript model"),
            std::string::npos)
      << out;
}

}  // namespace
}  // namespace deep_metrics_test
}  // namespace geodrive

#endif  // GEODRIVE_WITH_TORCH
