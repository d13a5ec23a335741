#include "geometry/depth_scale.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

TEST(DepthScale, ExactWithoutNoise) {
  std::vector<double> ref, est;
  for (int i = 1; i <= 100; ++i) {
    est.push_back(0.01 * i);
    ref.push_back(37.5 * 0.01 * i);
  }
  const DepthScaleResult r = FitDepthScale(ref, est);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_NEAR(r.scale, 37.5, 1e-9);
  EXPECT_EQ(r.num_inliers, 100);
  EXPECT_LT(r.residual_p99, 1e-9);
}

// The measurement: 3 % depth noise plus 10 % outlier LiDAR returns (points on a vehicle
// that the estimated depth misses -> much nearer, and random far returns) -> scale within 0.5 %.
TEST(DepthScale, RobustToNoiseAndOutliers) {
  auto& rng = test::Rng();
  std::uniform_real_distribution<double> depth(2.0, 60.0), unit(0, 1);
  std::normal_distribution<double> noise(0, 0.03);
  for (double true_scale : {0.05, 3.7, 42.0}) {
    std::vector<double> ref, est;
    for (int i = 0; i < 3000; ++i) {
      const double d = depth(rng);
      est.push_back(d / true_scale);
      double lidar = d * (1.0 + noise(rng));
      if (unit(rng) < 0.10) lidar = unit(rng) < 0.5 ? d * (0.2 + 0.5 * unit(rng)) : 80 + 40 * unit(rng);
      ref.push_back(lidar);
    }
    DepthScaleOptions options;
    options.seed = 3;
    const DepthScaleResult r = FitDepthScale(ref, est, options);
    ASSERT_TRUE(r.success) << r.message;
    const double rel = std::abs(r.scale / true_scale - 1.0);
    std::printf("true scale %.3f fitted %.5f (rel err %.4f %%), %s\n", true_scale, r.scale,
                100 * rel, r.BriefReport().c_str());
    EXPECT_LT(rel, 0.005);
    EXPECT_GT(r.inlier_fraction, 0.8);
  }
}

// The fit as first written (every hypothesis scored by testing every ratio,
// each percentile by a sort of its own): the reference FitDepthScale's faster
// counting must equal bit for bit.
DepthScaleResult ExhaustiveFit(const std::vector<double>& d_ref,
                               const std::vector<double>& d_est,
                               const DepthScaleOptions& o) {
  std::vector<double> lr, ref, est;
  for (size_t i = 0; i < d_ref.size(); ++i) {
    lr.push_back(std::log(d_ref[i] / d_est[i]));
    ref.push_back(d_ref[i]);
    est.push_back(d_est[i]);
  }
  const double thr = o.inlier_log_threshold;
  const auto count = [&](double c) {
    int n = 0;
    for (double r : lr) n += std::abs(r - c) < thr;
    return n;
  };
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t mid = v.size() / 2;
    return v.size() % 2 == 1 ? v[mid] : 0.5 * (v[mid] + v[mid - 1]);
  };
  double log_s = median(lr);
  std::mt19937_64 rng(o.seed);
  std::uniform_int_distribution<size_t> pick(0, lr.size() - 1);
  int best = count(log_s);
  for (int it = 0; it < o.ransac_iterations; ++it) {
    const double c = lr[pick(rng)];
    const int n = count(c);
    if (n > best) best = n, log_s = c;
  }
  std::vector<double> inl;
  for (double r : lr)
    if (std::abs(r - log_s) < thr) inl.push_back(r);
  log_s = median(inl);
  for (int it = 0; it < o.irls_iterations; ++it) {
    double wsum = 0, wr = 0;
    for (double r : lr) {
      const double e = (r - log_s) / o.cauchy_scale;
      const double w = 1.0 / (1.0 + e * e);
      wsum += w;
      wr += w * r;
    }
    const double next = wr / wsum;
    const bool converged = std::abs(next - log_s) < 1e-12;
    log_s = next;
    if (converged) break;
  }
  for (int it = 0; it < 3; ++it) {
    double sum = 0;
    int n = 0;
    for (double r : lr)
      if (std::abs(r - log_s) < thr) sum += r, ++n;
    if (n == 0) break;
    log_s = sum / n;
  }
  DepthScaleResult out;
  out.scale = std::exp(log_s);
  std::vector<double> res;
  for (size_t i = 0; i < lr.size(); ++i)
    if (std::abs(lr[i] - log_s) < thr)
      res.push_back(std::abs(ref[i] - out.scale * est[i]));
  out.num_inliers = static_cast<int>(res.size());
  const auto pct = [&](double p) {
    std::vector<double> v = res;
    std::sort(v.begin(), v.end());
    const double pos = p * (v.size() - 1);
    const size_t lo = static_cast<size_t>(std::floor(pos));
    const size_t hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (pos - lo) * (v[hi] - v[lo]);
  };
  out.residual_p50 = pct(0.5);
  out.residual_p90 = pct(0.9);
  out.residual_p99 = pct(0.99);
  return out;
}

// Ratios on a grid of steps of half the inlier band, so that many ties and
// many hypotheses exactly one band apart (where rounding decides) occur, plus
// noisy ones: the same scale, inlier count and residual percentiles as the
// exhaustive fit, bit for bit, for 40 seeds.
TEST(DepthScale, SortedInlierCountingEqualsTheExhaustiveFit) {
  auto& rng = test::Rng();
  std::uniform_int_distribution<int> step(-12, 12);
  std::uniform_real_distribution<double> depth(1.0, 50.0), unit(0, 1);
  for (uint64_t seed = 0; seed < 40; ++seed) {
    std::vector<double> ref, est;
    for (int i = 0; i < 400 + 37 * static_cast<int>(seed); ++i) {
      const double d = depth(rng);
      const double log_ratio =
          unit(rng) < 0.7 ? 0.05 * step(rng) : 0.6 * (unit(rng) - 0.5);
      est.push_back(d);
      ref.push_back(d * std::exp(log_ratio));
    }
    DepthScaleOptions o;
    o.seed = seed;
    const DepthScaleResult fast = FitDepthScale(ref, est, o);
    const DepthScaleResult slow = ExhaustiveFit(ref, est, o);
    ASSERT_TRUE(fast.success) << fast.message;
    EXPECT_EQ(fast.scale, slow.scale) << "seed " << seed;
    EXPECT_EQ(fast.num_inliers, slow.num_inliers) << "seed " << seed;
    EXPECT_EQ(fast.residual_p50, slow.residual_p50) << "seed " << seed;
    EXPECT_EQ(fast.residual_p90, slow.residual_p90) << "seed " << seed;
    EXPECT_EQ(fast.residual_p99, slow.residual_p99) << "seed " << seed;
  }
}

TEST(DepthScale, FailuresAreReported) {
  const DepthScaleResult few = FitDepthScale({1, 2, 3}, {1, 2, 3});
  EXPECT_FALSE(few.success);
  EXPECT_NE(few.message.find("too few"), std::string::npos);
  std::vector<double> ref(50, std::nan("")), est(50, 1.0);
  EXPECT_FALSE(FitDepthScale(ref, est).success);
  EXPECT_THROW(FitDepthScale({1, 2}, {1}), InputError);
  DepthScaleOptions bad;
  bad.inlier_log_threshold = -1;
  EXPECT_THROW(FitDepthScale({1}, {1}, bad), InputError);
}

TEST(DepthScale, BilinearSamplingSkipsInvalid) {
  cv::Mat depth(4, 4, CV_32F);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x) depth.at<float>(y, x) = 1.0f + x + 10.0f * y;
  cv::Mat invalid = cv::Mat::zeros(4, 4, CV_8U);
  // Bilinear of a linear function is exact.
  EXPECT_NEAR(SampleDepthBilinear(depth, invalid, 1.25, 2.5), 1.0 + 1.25 + 25.0, 1e-6);
  EXPECT_NEAR(SampleDepthBilinear(depth, cv::Mat(), 3.0, 3.0), 1.0 + 3 + 30, 1e-6);
  EXPECT_TRUE(std::isnan(SampleDepthBilinear(depth, invalid, 3.5, 1.0)));
  EXPECT_TRUE(std::isnan(SampleDepthBilinear(depth, invalid, -0.1, 1.0)));
  invalid.at<uint8_t>(2, 2) = 255;  // a dynamic pixel
  EXPECT_TRUE(std::isnan(SampleDepthBilinear(depth, invalid, 1.5, 1.5)));
  depth.at<float>(0, 0) = std::nanf("");
  EXPECT_TRUE(std::isnan(SampleDepthBilinear(depth, cv::Mat(), 0.5, 0.5)));
}

}  // namespace
}  // namespace geodrive
