// Uses the installed headers and library: composes two transforms and projects a point.
#include <dataset/scene_source.h>
#include <geodrive_version.h>
#include <geometry/camera.h>
#include <geometry/rigid3.h>

#include <cmath>
#include <cstdio>

int main() {
  using namespace geodrive;
  const Rigid3d world_from_cam(QuaternionFromAngleAxis(Eigen::Vector3d(0, 0.3, 0)),
                               Eigen::Vector3d(1, 2, 3));
  const Rigid3d cam_from_world = world_from_cam.Inverse();
  const Eigen::Vector3d p_world = world_from_cam * Eigen::Vector3d(0.1, -0.2, 5.0);
  const PinholeCamera camera(1266.0, 1266.0, 816.0, 491.0, 1600, 900);
  const Eigen::Vector2d uv = camera.Project(cam_from_world * p_world);
  const Eigen::Vector2d expected(1266.0 * 0.1 / 5.0 + 816.0, 1266.0 * -0.2 / 5.0 + 491.0);
  const double err = (uv - expected).norm();
  std::printf("geodrive %s consumer: reprojection error %.3g px\n", GEODRIVE_VERSION, err);
  // A dataset-module call: the scene-source registry.
  const std::vector<std::string> sources = SceneSourceNames();
  std::printf("scene sources: %zu (first %s)\n", sources.size(),
              sources.front().c_str());
  return err < 1e-9 && sources.size() >= 5 ? 0 : 1;
}
