#include "geometry/depth_scale.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

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
