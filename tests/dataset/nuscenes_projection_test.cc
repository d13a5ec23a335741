// nuScenes projections against hand-computed references and brute-force
// formulas.

#include "dataset/nuscenes_projection.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/common/test_util.h"

namespace geodrive {
namespace {

Eigen::Matrix3d TestK() {
  Eigen::Matrix3d K;
  K << 1266.4, 0, 816.3, 0, 1266.4, 491.5, 0, 0, 1;
  return K;
}

TEST(PostProcessCoords, ClipsTheHullToTheCanvas) {
  // Triangle (-100, 100), (200, 100), (200, 400) on a 100x300 canvas: the hull
  // crosses x=0 and x=100; the clipped polygon spans x in [0, 100], y from 100
  // to the hypotenuse at x=100 (y = 100 + (100+100)*300/300 = 300).
  const auto box =
      PostProcessCoords({{-100, 100}, {200, 100}, {200, 400}}, 100, 300);
  ASSERT_TRUE(box.has_value());
  EXPECT_NEAR(box->xmin, 0, 1e-12);
  EXPECT_NEAR(box->xmax, 100, 1e-12);
  EXPECT_NEAR(box->ymin, 100, 1e-12);
  EXPECT_NEAR(box->ymax, 300, 1e-9);
  // Entirely outside.
  EXPECT_FALSE(PostProcessCoords({{-10, -10}, {-5, -20}, {-1, -1}}, 100, 100)
                   .has_value());
  // A hull enclosing the canvas gives the canvas.
  const auto all =
      PostProcessCoords({{-1e4, -1e4}, {1e4, -1e4}, {0, 1e4}}, 160, 90);
  ASSERT_TRUE(all.has_value());
  EXPECT_NEAR(all->xmin, 0, 1e-9);
  EXPECT_NEAR(all->ymax, 90, 1e-9);
  EXPECT_NEAR(all->xmax, 160, 1e-9);
  // Interior points: the plain min/max.
  const auto in =
      PostProcessCoords({{10, 20}, {30, 5}, {25, 40}, {15, 25}}, 100, 100);
  ASSERT_TRUE(in.has_value());
  EXPECT_DOUBLE_EQ(in->xmin, 10);
  EXPECT_DOUBLE_EQ(in->ymin, 5);
  EXPECT_DOUBLE_EQ(in->xmax, 30);
  EXPECT_DOUBLE_EQ(in->ymax, 40);
}

// For random boxes: when all corners are in front and project inside, BoxTo2d
// is the min/max of the projected corners; otherwise it lies within the canvas
// and inside that min/max.
TEST(BoxTo2d, MatchesCornerBoundsAndStaysInCanvas) {
  std::uniform_real_distribution<double> U(-1, 1);
  const Eigen::Matrix3d K = TestK();
  int inside = 0, partial = 0;
  for (int trial = 0; trial < 500; ++trial) {
    NuscenesBox box;
    box.center = Eigen::Vector3d(15 * U(test::Rng()), 2 * U(test::Rng()),
                                 20 + 18 * U(test::Rng()));
    box.wlh = Eigen::Vector3d(2 + U(test::Rng()), 4.5 + U(test::Rng()), 1.6);
    box.orientation = Eigen::Quaterniond::UnitRandom();
    Box2d bound{1e9, 1e9, -1e9, -1e9};
    bool all_in = true;
    for (const auto& c : box.Corners()) {
      const Eigen::Vector3d h = K * c;
      const double u = h.x() / h.z(), v = h.y() / h.z();
      bound = {std::min(bound.xmin, u), std::min(bound.ymin, v),
               std::max(bound.xmax, u), std::max(bound.ymax, v)};
      all_in = all_in && c.z() > 0 && u >= 0 && u <= 1600 && v >= 0 && v <= 900;
    }
    const auto b = BoxTo2d(box, K, 1600, 900);
    if (all_in) {
      ASSERT_TRUE(b.has_value());
      EXPECT_NEAR(b->xmin, bound.xmin, 1e-9);
      EXPECT_NEAR(b->ymax, bound.ymax, 1e-9);
      EXPECT_TRUE(BoxInImage(box, K, 1600, 900, BoxVisibility::kAll));
      ++inside;
    } else if (b) {
      EXPECT_GE(b->xmin, 0);
      EXPECT_LE(b->xmax, 1600);
      EXPECT_GE(b->ymin, 0);
      EXPECT_LE(b->ymax, 900);
      ++partial;
    }
  }
  EXPECT_GT(inside, 100);
  EXPECT_GT(partial, 20);
}

TEST(BoxInImage, AnyAllNoneAsTheDevkit) {
  const Eigen::Matrix3d K = TestK();
  NuscenesBox box;
  box.wlh = Eigen::Vector3d(2, 4, 1.5);
  box.center = Eigen::Vector3d(0, 0, 20);
  EXPECT_TRUE(BoxInImage(box, K, 1600, 900, BoxVisibility::kAll));
  // Straddling the left border: some corners visible.
  box.center = Eigen::Vector3d(-816.3 / 1266.4 * 20, 0, 20);
  EXPECT_TRUE(BoxInImage(box, K, 1600, 900, BoxVisibility::kAny));
  EXPECT_FALSE(BoxInImage(box, K, 1600, 900, BoxVisibility::kAll));
  // Behind the camera.
  box.center = Eigen::Vector3d(0, 0, -20);
  EXPECT_FALSE(BoxInImage(box, K, 1600, 900, BoxVisibility::kAny));
  EXPECT_TRUE(BoxInImage(box, K, 1600, 900, BoxVisibility::kNone));
  EXPECT_FALSE(BoxTo2d(box, K, 1600, 900).has_value());
  // Corners with z in (0, 1] are not "visible" for box_in_image (z > 1 rule).
  box.center = Eigen::Vector3d(0, 0, 0.9);
  box.wlh = Eigen::Vector3d(0.1, 0.1, 0.1);
  EXPECT_FALSE(BoxInImage(box, K, 1600, 900, BoxVisibility::kAny));
}

// The five-transform chain equals the composed rigid transform (to float32
// storage precision) and the kept set follows the devkit mask exactly for
// points away from the borders.
TEST(MapPointCloudToImage, FiveTransformsEqualTheComposedChain) {
  std::uniform_real_distribution<double> U(-1, 1);
  const Rigid3d ego_from_lidar(
      QuaternionFromWxyz(0.7071, 0, 0, -0.7071).normalized(),
      Eigen::Vector3d(0.944, 0, 1.84));
  const Rigid3d g_lidar(QuaternionFromAngleAxis(Eigen::Vector3d(0, 0, 0.3)),
                        Eigen::Vector3d(400, 1100, 0));
  const Rigid3d g_cam(QuaternionFromAngleAxis(Eigen::Vector3d(0, 0, 0.31)),
                      Eigen::Vector3d(400.4, 1100.2, 0));
  const Rigid3d ego_from_cam(
      QuaternionFromWxyz(0.4998, -0.5030, 0.4998, -0.4974).normalized(),
      Eigen::Vector3d(1.70, 0.016, 1.51));
  const Rigid3d cam_from_lidar =
      ego_from_cam.Inverse() * g_cam.Inverse() * g_lidar * ego_from_lidar;
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < 20000; ++i) {
    points.emplace_back(40 * U(test::Rng()), 40 * U(test::Rng()),
                        3 * U(test::Rng()));
  }
  const Eigen::Matrix3d K = TestK();
  const auto chain = MapPointCloudToImage(points, ego_from_lidar, g_lidar,
                                          g_cam, ego_from_cam, K, 1600, 900);
  const auto direct =
      ProjectLidarToImage(points, cam_from_lidar.ToMatrix(), K, 1600, 900);
  EXPECT_GT(chain.size(), 1000u);
  EXPECT_NEAR(static_cast<double>(chain.size()),
              static_cast<double>(direct.size()), 2);
  // Brute force: the devkit mask on the composed transform.
  size_t j = 0;
  for (size_t i = 0; i < chain.size(); ++i) {
    while (j < direct.size() && direct.indices[j] < chain.indices[i]) ++j;
    if (j == direct.size() || direct.indices[j] != chain.indices[i]) continue;
    EXPECT_LT((chain.pixels[i] - direct.pixels[j]).norm(), 0.05);
    EXPECT_NEAR(chain.depths[i], direct.depths[j], 1e-3);
  }
  LidarProjectionOptions far;
  far.min_dist = 10;
  for (double d :
       ProjectLidarToImage(points, cam_from_lidar.ToMatrix(), K, 1600, 900, far)
           .depths) {
    ASSERT_GT(d, 10);
  }
}

}  // namespace
}  // namespace geodrive
