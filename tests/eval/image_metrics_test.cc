// PSNR / SSIM against Debian's python3-skimage and against hand-computable
// cases.

#include "eval/image_metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "geometry/npy.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

// A textured image (smooth blobs + stripes + noise) with saturated corners, RGB
// or gray.
cv::Mat MakeImage(int rows, int cols, int channels, int noise, uint32_t seed) {
  std::mt19937 rng(seed);
  cv::Mat base(rows, cols, CV_8UC(channels));
  cv::RNG(seed).fill(base, cv::RNG::UNIFORM, 0, 256);  // not the global RNG
  cv::GaussianBlur(base, base, cv::Size(0, 0), 2.0);
  for (int r = 0; r < rows; ++r) {
    uint8_t* p = base.ptr<uint8_t>(r);
    for (int c = 0; c < cols * channels; ++c) {
      int v = p[c] + static_cast<int>(40 * std::sin(0.3 * c + 0.1 * r));
      if (noise > 0) v += static_cast<int>(rng() % (2 * noise + 1)) - noise;
      if (r < rows / 5 && c < cols * channels / 5) v = 255;  // saturated block
      if (r > rows - rows / 6 && c > cols * channels - cols * channels / 6)
        v = 0;
      p[c] = static_cast<uint8_t>(std::clamp(v, 0, 255));
    }
  }
  return base;
}

cv::Mat Perturb(const cv::Mat& image, int noise, uint32_t seed) {
  std::mt19937 rng(seed);
  cv::Mat out = image.clone();
  uint8_t* p = out.data;
  for (size_t i = 0; i < out.total() * out.channels(); ++i) {
    const int v = p[i] + static_cast<int>(rng() % (2 * noise + 1)) - noise;
    p[i] = static_cast<uint8_t>(std::clamp(v, 0, 255));
  }
  return out;
}

void SaveNpy(const std::string& path, const cv::Mat& m) {
  std::vector<int64_t> shape = {m.rows, m.cols};
  if (m.channels() > 1) shape.push_back(m.channels());
  if (m.depth() == CV_8U) {
    WriteNpy(path, NpyArray::Uint8(shape, m.ptr<uint8_t>()));
  } else {
    WriteNpy(path, NpyArray::Float64(shape, m.ptr<double>()));
  }
}

// Runs tests/eval/skimage_reference.py; returns {psnr, ssim}.
std::pair<double, double> SkimageReference(const cv::Mat& a,
                                           const cv::Mat& b,
                                           bool luma) {
  const std::string dir = test::MakeTempDir("skimage_ref");
  SaveNpy(dir + "/a.npy", a);
  SaveNpy(dir + "/b.npy", b);
  std::string out;
  const int rc = test::RunCommand(
      std::string(test::kDebianPython) +
          " " GEODRIVE_SOURCE_DIR "/tests/eval/skimage_reference.py " + dir +
          "/a.npy " + dir + "/b.npy" + (luma ? " luma" : ""),
      &out);
  EXPECT_EQ(rc, 0) << out;
  // Last line holds the numbers (warnings may precede it).
  const size_t end = out.find_last_not_of("\n");
  const size_t start = out.find_last_of('\n', end);
  std::istringstream line(
      out.substr(start == std::string::npos ? 0 : start + 1));
  double psnr = NAN, ssim = NAN;
  line >> psnr >> ssim;
  return {psnr, ssim};
}

struct Case {
  int rows, cols, channels, noise;
};

TEST(ImageMetrics, MatchesSkimageOnGeneratedImages) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("skimage");
  const Case cases[] = {{64, 80, 3, 20},  {11, 11, 3, 30}, {37, 23, 1, 5},
                        {120, 97, 3, 60}, {48, 720, 3, 3}, {30, 41, 1, 120}};
  uint32_t seed = 1;
  for (const Case& c : cases) {
    const cv::Mat gt = MakeImage(c.rows, c.cols, c.channels, 10, seed++);
    const cv::Mat pred = Perturb(gt, c.noise, seed++);
    const auto [ref_psnr, ref_ssim] = SkimageReference(gt, pred, false);
    const double psnr = Psnr(gt, pred);
    const double ssim = Ssim(gt, pred);
    std::printf(
        "%dx%dx%d noise %d: PSNR %.10f (skimage %.10f), SSIM %.12f (skimage "
        "%.12f)\n",
        c.cols, c.rows, c.channels, c.noise, psnr, ref_psnr, ssim, ref_ssim);
    // Same formulas in float64: only summation order differs (~1e-13); 1e-4 is
    // the contract.
    EXPECT_NEAR(psnr, ref_psnr, 1e-9);
    EXPECT_NEAR(ssim, ref_ssim, 1e-9);
  }
}

TEST(ImageMetrics, LumaMatchesSkimage) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("skimage");
  const cv::Mat gt = MakeImage(50, 70, 3, 10, 7);
  const cv::Mat pred = Perturb(gt, 25, 8);
  const auto [ref_psnr, ref_ssim] = SkimageReference(gt, pred, true);
  const cv::Mat yg = LumaBt601(gt), yp = LumaBt601(pred);
  std::printf(
      "luma: PSNR-Y %.10f (skimage %.10f), SSIM-Y %.12f (skimage %.12f)\n",
      Psnr(yg, yp), ref_psnr, Ssim(yg, yp), ref_ssim);
  EXPECT_NEAR(Psnr(yg, yp), ref_psnr, 1e-9);
  EXPECT_NEAR(Ssim(yg, yp), ref_ssim, 1e-9);
}

TEST(ImageMetrics, FusedKernelEqualsGenericFilterPath) {
  SsimOptions generic;
  generic.fused_kernel = false;
  for (int channels : {1, 3}) {
    const cv::Mat a = MakeImage(45, 61, channels, 10, 11);
    const cv::Mat b = Perturb(a, 40, 12);
    EXPECT_NEAR(Ssim(a, b), Ssim(a, b, generic), 1e-12) << channels;
    cv::Mat fa, fb;  // float64 input takes the same route
    a.convertTo(fa, CV_64F);
    b.convertTo(fb, CV_64F);
    EXPECT_NEAR(Ssim(fa, fb), Ssim(a, b), 1e-12) << channels;
  }
}

// An 11x11 image has exactly one valid SSIM pixel per channel, so
// SsimPerChannel on 11x11 patches gives single SSIM-map values: this compares
// the fused kernel (and its float32-reciprocal division) with skimage pixel by
// pixel, including flat, saturated, black-vs-white and pure-noise windows.
TEST(ImageMetrics, PerPixelSsimMatchesSkimageOn11x11Patches) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("skimage");
  constexpr int kPatches = 160;
  const cv::Mat texture = MakeImage(120, 160, 3, 10, 31);
  const cv::Mat texture_b = Perturb(texture, 45, 32);
  std::mt19937 rng(33);
  cv::RNG noise(34);  // not cv::randu: its global state depends on test order
  std::vector<uint8_t> pa, pb;
  for (int i = 0; i < kPatches; ++i) {
    cv::Mat a, b;
    const int kind = i % 8;
    if (kind < 4) {  // crops of a textured pair (incl. saturated corners)
      const int r = static_cast<int>(rng() % (texture.rows - 11));
      const int c = static_cast<int>(rng() % (texture.cols - 11));
      const cv::Rect roi(c, r, 11, 11);
      a = texture(roi).clone();
      b = (kind == 3 ? texture(roi) : texture_b(roi)).clone();
    } else if (kind == 4) {  // independent uniform noise
      a.create(11, 11, CV_8UC3);
      b.create(11, 11, CV_8UC3);
      noise.fill(a, cv::RNG::UNIFORM, 0, 256);
      noise.fill(b, cv::RNG::UNIFORM, 0, 256);
    } else if (kind == 5) {  // black vs white / flat vs flat
      a = cv::Mat(11, 11, CV_8UC3, cv::Scalar(0, 255, 17 * (i % 15)));
      b = cv::Mat(11, 11, CV_8UC3, cv::Scalar(255, 255, 3 * (i % 85)));
    } else if (kind == 6) {  // flat vs noise
      a = cv::Mat(11, 11, CV_8UC3, cv::Scalar(0, 128, 255));
      b.create(11, 11, CV_8UC3);
      noise.fill(b, cv::RNG::UNIFORM, 0, 256);
    } else {  // binary 0/255 noise against its small perturbation
      a.create(11, 11, CV_8UC3);
      noise.fill(a, cv::RNG::UNIFORM, 0, 2);
      a *= 255;
      b = Perturb(a, 3, 1000 + i);
    }
    pa.insert(pa.end(), a.data, a.data + a.total() * 3);
    pb.insert(pb.end(), b.data, b.data + b.total() * 3);
  }
  const std::string dir = test::MakeTempDir("ssim_patches");
  WriteNpy(dir + "/a.npy", NpyArray::Uint8({kPatches, 11, 11, 3}, pa.data()));
  WriteNpy(dir + "/b.npy", NpyArray::Uint8({kPatches, 11, 11, 3}, pb.data()));
  {
    std::FILE* f = std::fopen((dir + "/ref.py").c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs(
        "import sys\n"
        "import numpy as np\n"
        "from skimage.metrics import structural_similarity as ssim\n"
        "a = np.load(sys.argv[1] + '/a.npy')\n"
        "b = np.load(sys.argv[1] + '/b.npy')\n"
        "for i in range(a.shape[0]):\n"
        "    print(' '.join('%.17g' % ssim(a[i, :, :, c], b[i, :, :, c],\n"
        "          gaussian_weights=True, sigma=1.5,\n"
        "          use_sample_covariance=False, data_range=255)\n"
        "          for c in range(3)))\n",
        f);
    std::fclose(f);
  }
  std::string out;
  ASSERT_EQ(test::RunCommand(
                std::string(test::kDebianPython) + " " + dir + "/ref.py " + dir,
                &out),
            0)
      << out;
  std::istringstream lines(out);
  double max_error = 0, min_ssim = 1, max_ssim = -1;
  for (int i = 0; i < kPatches; ++i) {
    const cv::Mat a(11, 11, CV_8UC3, pa.data() + i * 363);
    const cv::Mat b(11, 11, CV_8UC3, pb.data() + i * 363);
    const std::vector<double> ours = SsimPerChannel(a, b);
    for (int c = 0; c < 3; ++c) {
      double ref = NAN;
      lines >> ref;
      ASSERT_FALSE(std::isnan(ref)) << "patch " << i << " channel " << c;
      EXPECT_NEAR(ours[c], ref, 1e-9) << "patch " << i << " channel " << c;
      max_error = std::max(max_error, std::abs(ours[c] - ref));
      min_ssim = std::min(min_ssim, ref);
      max_ssim = std::max(max_ssim, ref);
    }
  }
  std::printf(
      "%d SSIM-map pixels: max |geodrive - skimage| %.3g (SSIM range %.4f .. "
      "%.4f)\n",
      3 * kPatches, max_error, min_ssim, max_ssim);
}

// The fused kernel divides through a float32 reciprocal refined in float64
// when the denominator range allows it (uint8 input, moderate data_range), and
// exactly otherwise; both must equal the generic five-map path.
TEST(ImageMetrics, FusedKernelEqualsGenericPathForAnyDataRange) {
  SsimOptions generic;
  generic.fused_kernel = false;
  const cv::Mat a = MakeImage(40, 57, 3, 10, 41);
  const cv::Mat b = Perturb(a, 70, 42);
  for (double range : {1.0, 255.0, 65535.0, 1e12}) {
    SsimOptions fused;
    fused.data_range = generic.data_range = range;
    const std::vector<double> f = SsimPerChannel(a, b, fused);
    const std::vector<double> g = SsimPerChannel(a, b, generic);
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(f[c], g[c], 1e-12) << "data_range " << range << " c " << c;
  }
}

TEST(ImageMetrics, SsimClosedFormOnFlatImages) {
  // Flat images: variances vanish, SSIM = (2 m1 m2 + C1) / (m1^2 + m2^2 + C1)
  // for any window.
  for (double truncate :
       {3.5, 2.8, 4.2}) {  // radius 5 (fused), 4 and 6 (generic)
    SsimOptions options;
    options.truncate = truncate;
    const cv::Mat a(40, 50, CV_8UC3, cv::Scalar(100, 100, 100));
    const cv::Mat b(40, 50, CV_8UC3, cv::Scalar(130, 130, 130));
    const double c1 = std::pow(0.01 * 255, 2);
    const double expected =
        (2.0 * 100 * 130 + c1) / (100.0 * 100 + 130.0 * 130 + c1);
    EXPECT_NEAR(Ssim(a, b, options), expected, 1e-12)
        << "truncate " << truncate;
    const cv::Mat t = MakeImage(40, 50, 3, 10, 3);
    EXPECT_NEAR(Ssim(t, t, options), 1.0, 1e-12);
  }
}

TEST(ImageMetrics, PsnrHandComputed) {
  cv::Mat a(10, 10, CV_8UC3, cv::Scalar(10, 20, 30));
  cv::Mat b = a.clone();
  b.at<cv::Vec3b>(0, 0)[0] = 20;  // one element off by 10: MSE = 100 / 300
  const double expected = 10 * std::log10(255.0 * 255.0 / (100.0 / 300.0));
  EXPECT_NEAR(Psnr(a, b), expected, 1e-12);
  EXPECT_EQ(Psnr(a, a), 100.0);  // identical -> the cap, not +inf
  PsnrOptions unit;
  unit.data_range = 1.0;
  cv::Mat fa, fb;
  a.convertTo(fa, CV_64F, 1 / 255.0);
  b.convertTo(fb, CV_64F, 1 / 255.0);
  EXPECT_NEAR(Psnr(fa, fb, unit), expected,
              1e-9);  // [0, 1] frames, R = 1: same number
}

TEST(ImageMetrics, VideoMeansAndBadInput) {
  std::vector<cv::Mat> gt, pred;
  for (int i = 0; i < 4; ++i) {
    gt.push_back(MakeImage(32, 40, 3, 10, 100 + i));
    pred.push_back(Perturb(gt.back(), 5 + 10 * i, 200 + i));
  }
  FrameMetricsOptions options;
  options.luma = true;
  const VideoScores s = CompareVideos(pred, gt, options, "clip");
  ASSERT_EQ(s.frames.size(), 4u);
  double mean = 0;
  for (int i = 0; i < 4; ++i) {
    EXPECT_DOUBLE_EQ(s.frames[i].ssim_rgb, Ssim(pred[i], gt[i]));
    mean += s.frames[i].psnr_rgb / 4;
  }
  EXPECT_NEAR(s.mean.psnr_rgb, mean, 1e-12);
  EXPECT_GT(s.frames[0].psnr_rgb,
            s.frames[3].psnr_rgb);  // more noise, lower PSNR
  EXPECT_FALSE(std::isnan(s.mean.ssim_y));

  auto expect_error = [&](const std::vector<cv::Mat>& p,
                          const std::vector<cv::Mat>& g,
                          const std::string& needle) {
    try {
      CompareVideos(p, g, {}, "clip");
      ADD_FAILURE() << "no error for " << needle;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
          << e.what();
    }
  };
  expect_error({pred.begin(), pred.begin() + 3}, gt,
               "frame counts differ (predicted 3, ground truth 4)");
  expect_error({}, gt, "no frames");
  std::vector<cv::Mat> small = pred;
  small[2] = cv::Mat(30, 40, CV_8UC3, cv::Scalar(0));
  expect_error(small, gt, "frame 2: image sizes differ (40x30 vs 40x32)");
  EXPECT_THROW(Ssim(cv::Mat(8, 8, CV_8UC3), cv::Mat(8, 8, CV_8UC3)),
               InputError);  // < 11x11
}

}  // namespace
}  // namespace geodrive
