// Fréchet distance against scipy's sqrtm route (pytorch-fid) and closed forms.

#include "eval/frechet.h"

#include <gtest/gtest.h>

#include <Eigen/QR>
#include <cstdio>
#include <random>

#include "geometry/npy.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

Eigen::MatrixXd RandomFeatures(int n,
                               int d,
                               double shift,
                               const Eigen::VectorXd& scales) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd rot =
      Eigen::MatrixXd::NullaryExpr(d, d, [&] { return normal(test::Rng()); });
  const Eigen::MatrixXd q =
      Eigen::HouseholderQR<Eigen::MatrixXd>(rot).householderQ();
  Eigen::MatrixXd f =
      Eigen::MatrixXd::NullaryExpr(n, d, [&] { return normal(test::Rng()); });
  f = (f * scales.asDiagonal()) * q.transpose();
  f.array() += shift;
  return f;
}

double ScipyReference(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  const std::string dir = test::MakeTempDir("frechet_ref");
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>
      ra = a,
      rb = b;
  WriteNpy(dir + "/a.npy", NpyArray::Float64({a.rows(), a.cols()}, ra.data()));
  WriteNpy(dir + "/b.npy", NpyArray::Float64({b.rows(), b.cols()}, rb.data()));
  std::string out;
  const int rc = test::RunCommand(
      std::string(test::kDebianPython) +
          " " GEODRIVE_SOURCE_DIR "/tests/eval/scipy_frechet_reference.py " +
          dir + "/a.npy " + dir + "/b.npy",
      &out);
  EXPECT_EQ(rc, 0) << out;
  const size_t end = out.find_last_not_of("\n");
  const size_t start = out.find_last_of('\n', end);
  return std::stod(out.substr(start == std::string::npos ? 0 : start + 1));
}

TEST(Frechet, MatchesScipySqrtmOnRandomAndIllConditioned) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("scipy");
  struct Case {
    const char* name;
    int n, d;
    double lo_scale, hi_scale;
  };
  const Case cases[] = {{"random", 400, 16, 0.5, 2.0},
                        {"ill-conditioned 1e-4..1e2", 300, 24, 1e-4, 1e2},
                        {"ill-conditioned 1e-6..1e3", 500, 32, 1e-6, 1e3},
                        {"N barely > D", 41, 40, 0.1, 1.0}};
  for (const Case& c : cases) {
    Eigen::VectorXd scales(c.d), scales2(c.d);
    for (int i = 0; i < c.d; ++i) {
      const double t = static_cast<double>(i) / (c.d - 1);
      scales[i] = c.lo_scale * std::pow(c.hi_scale / c.lo_scale, t);
      scales2[i] = scales[i] * (1.0 + 0.3 * std::sin(i));
    }
    const Eigen::MatrixXd a = RandomFeatures(c.n, c.d, 0.0, scales);
    const Eigen::MatrixXd b = RandomFeatures(c.n + 7, c.d, 0.05, scales2);
    const FrechetResult r = FrechetDistance(ComputeFeatureStatistics(a, "a"),
                                            ComputeFeatureStatistics(b, "b"));
    const double ref = ScipyReference(a, b);
    const double rel = std::abs(r.distance - ref) / std::abs(ref);
    std::printf("%s (N %d, D %d): ours %.12g scipy %.12g rel diff %.2e\n",
                c.name, c.n, c.d, r.distance, ref, rel);
    EXPECT_LT(rel, 1e-6) << c.name;
  }
}

TEST(Frechet, ClosedFormsAndStatistics) {
  // Commuting diagonal covariances: tr sqrt(S1 S2) = sum sqrt(a_i b_i).
  FeatureStatistics a, b;
  a.mean = Eigen::Vector3d(1, 2, 3);
  b.mean = Eigen::Vector3d(1, 0, 3);
  a.cov = Eigen::Vector3d(4, 9, 1).asDiagonal();
  b.cov = Eigen::Vector3d(1, 4, 16).asDiagonal();
  const double expected = 4.0 + (4 + 9 + 1) + (1 + 4 + 16) - 2 * (2 + 6 + 4);
  EXPECT_NEAR(FrechetDistance(a, b).distance, expected, 1e-12);
  EXPECT_NEAR(FrechetDistance(a, a).distance, 0.0, 1e-12);

  // Unbiased covariance (N - 1) as np.cov.
  Eigen::MatrixXd f(3, 2);
  f << 1, 2, 3, 4, 5, 9;
  const FeatureStatistics s = ComputeFeatureStatistics(f);
  EXPECT_NEAR(s.mean[1], 5.0, 1e-15);
  EXPECT_NEAR(s.cov(0, 0), 4.0, 1e-12);   // ((−2)² + 0 + 2²) / 2
  EXPECT_NEAR(s.cov(0, 1), 7.0, 1e-12);   // ((−2)(−3) + 0 + 2·4) / 2
  EXPECT_NEAR(s.cov(1, 1), 13.0, 1e-12);  // (9 + 1 + 16) / 2
}

TEST(Frechet, FewerSamplesThanDimensionsIsAnError) {
  const Eigen::MatrixXd f = Eigen::MatrixXd::Random(10, 64);
  try {
    ComputeFeatureStatistics(f, "generated.mp4 features");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(
        std::string(e.what()).find("10 samples for 64-dimensional features"),
        std::string::npos)
        << e.what();
  }
  FeatureStatistics a, b;
  a.mean = Eigen::VectorXd::Zero(3);
  a.cov = Eigen::MatrixXd::Identity(3, 3);
  b.mean = Eigen::VectorXd::Zero(4);
  b.cov = Eigen::MatrixXd::Identity(4, 4);
  EXPECT_THROW(FrechetDistance(a, b), InputError);
}

TEST(Frechet, StatisticsRoundTripThroughNpy) {
  const Eigen::MatrixXd f =
      RandomFeatures(50, 6, 1.0, Eigen::VectorXd::LinSpaced(6, 0.5, 3));
  const FeatureStatistics s = ComputeFeatureStatistics(f);
  const std::string prefix = test::MakeTempDir("frechet_stats") + "/ref";
  SaveFeatureStatistics(prefix, s);
  const FeatureStatistics loaded = LoadFeatureStatistics(prefix);
  EXPECT_THAT(loaded.mean, test::EigenNear(s.mean, 0.0));
  EXPECT_THAT(loaded.cov, test::EigenNear(s.cov, 0.0));
  EXPECT_EQ(FrechetDistance(loaded, s).distance,
            FrechetDistance(s, s).distance);
  EXPECT_THROW(LoadFeatureStatistics(prefix + "_missing"), InputError);
}

// Cached statistics that are not covariances are refused when loaded (a
// sign-flipped or transposed sigma gave FID -4e6 written as a figure).
TEST(Frechet, CachedStatisticsThatAreNotCovariancesAreRefused) {
  const Eigen::MatrixXd f =
      RandomFeatures(60, 5, 0.0, Eigen::VectorXd::LinSpaced(5, 0.5, 2));
  const FeatureStatistics good = ComputeFeatureStatistics(f);
  const std::string dir = test::MakeTempDir("frechet_bad_cov");
  auto refused = [&](const Eigen::MatrixXd& cov, const char* what) {
    FeatureStatistics s = good;
    s.cov = cov;
    SaveFeatureStatistics(dir + "/" + what, s);
    try {
      LoadFeatureStatistics(dir + "/" + what);
      ADD_FAILURE() << what << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(std::string(what) + "_sigma.npy"),
                std::string::npos)
          << e.what();
      EXPECT_NE(std::string(e.what()).find("not a covariance"),
                std::string::npos);
    }
  };
  Eigen::MatrixXd negative = good.cov;
  negative(2, 2) = -4e6;
  refused(negative, "negative_variance");
  refused(-good.cov, "sign_flipped");
  Eigen::MatrixXd asymmetric = good.cov;
  asymmetric(0, 4) += 0.5;
  refused(asymmetric, "asymmetric");
  Eigen::MatrixXd indefinite = Eigen::MatrixXd::Identity(5, 5);
  indefinite(0, 1) = indefinite(1, 0) = 2.0;  // eigenvalues 3 and -1
  refused(indefinite, "indefinite");
  // A rank-deficient covariance (PSD, eigenvalue 0) is a covariance.
  Eigen::MatrixXd singular = Eigen::MatrixXd::Zero(5, 5);
  singular(0, 0) = 1.0;
  FeatureStatistics s = good;
  s.cov = singular;
  SaveFeatureStatistics(dir + "/singular", s);
  EXPECT_NO_THROW(LoadFeatureStatistics(dir + "/singular"));
  // And a distance that cannot be one is never returned.
  FeatureStatistics bad = good;
  bad.cov = negative;
  EXPECT_THROW(FrechetDistance(bad, good), InputError);
}

}  // namespace
}  // namespace geodrive
