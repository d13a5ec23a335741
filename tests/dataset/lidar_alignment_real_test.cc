// LiDAR depth-scale fitting on REAL data (../shared/data/real/nuscenes_n015): a sparse LiDAR
// depth image of CAM_FRONT, compared against itself scaled by a known factor with 20 % of the
// pixels corrupted, must give back that factor within 0.5 %.

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <random>

#include "dataset/nuscenes_projection.h"
#include "geometry/depth_scale.h"
#include "geometry/point_cloud_io.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

TEST(LidarScaleReal, SparseDepthImageOfCamFrontRecoversKnownFactor) {
  const std::string dir = test::RealDataPath("nuscenes_n015/");
  std::ifstream in(dir + "info.json");
  ASSERT_TRUE(in.good()) << "missing real data at " << dir;
  const nlohmann::json info = nlohmann::json::parse(in)["data_list"][0];
  const auto& cam = info["images"]["CAM_FRONT"];
  Eigen::Matrix4d lidar2cam;
  Eigen::Matrix3d K;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) lidar2cam(r, c) = cam["lidar2cam"][r][c].get<double>();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) K(r, c) = cam["cam2img"][r][c].get<double>();
  const PointCloud cloud = ReadNuscenesLidarBin(
      dir + "n015-2018-07-24-11-22-45+0800__LIDAR_TOP__1532402927647951.pcd.bin");
  const LidarProjection proj = ProjectLidarToImage(cloud.positions, lidar2cam, K, 1600, 900);
  ASSERT_EQ(proj.size(), 3053u);  // the README's oracle for the devkit rule

  // Sparse depth image (nearest return per pixel) of the real sweep.
  cv::Mat sparse(900, 1600, CV_32F, cv::Scalar(0));
  for (size_t i = 0; i < proj.size(); ++i) {
    const int u = static_cast<int>(std::lround(proj.pixels[i].x()));
    const int v = static_cast<int>(std::lround(proj.pixels[i].y()));
    float& d = sparse.at<float>(v, u);
    if (d == 0 || proj.depths[i] < d) d = static_cast<float>(proj.depths[i]);
  }
  std::vector<double> d_ref, d_est;
  auto& rng = test::Rng();
  std::uniform_real_distribution<double> unit(0, 1);
  const double factor = 7.25;  // d_ref = factor * d_est
  for (int v = 0; v < sparse.rows; ++v) {
    for (int u = 0; u < sparse.cols; ++u) {
      const float d = sparse.at<float>(v, u);
      if (d <= 0) continue;
      d_est.push_back(d / factor);
      double ref = d;
      if (unit(rng) < 0.2) ref = unit(rng) < 0.5 ? d * (0.1 + 0.6 * unit(rng)) : d * (1.5 + 3 * unit(rng));
      d_ref.push_back(ref);
    }
  }
  const DepthScaleResult r = FitDepthScale(d_ref, d_est);
  ASSERT_TRUE(r.success) << r.message;
  const double rel = std::abs(r.scale / factor - 1);
  std::printf("real CAM_FRONT sparse depth: %d pixels, 20%% corrupted: fitted %.5f vs %.5f "
              "(rel err %.4f %%), %s\n",
              r.num_points, r.scale, factor, 100 * rel, r.BriefReport().c_str());
  EXPECT_LT(rel, 0.005);
}

}  // namespace
}  // namespace geodrive
