#include "render/footprint.h"

#include <cmath>

namespace geodrive {

void SetCaptureFootprints(const PinholeCamera& camera,
                          const Rigid3d& cam_from_world,
                          PointCloud* cloud) {
  const Eigen::Matrix3d r =
      cam_from_world.rotation.normalized().toRotationMatrix();
  const Eigen::RowVector3d zrow = r.row(2);
  const double tz = cam_from_world.translation.z();
  cloud->footprints.resize(cloud->size());
  for (size_t i = 0; i < cloud->size(); ++i) {
    const double z = zrow.dot(cloud->positions[i].cast<double>()) + tz;
    cloud->footprints[i] = CaptureFootprint(camera, z);
  }
}

}  // namespace geodrive
