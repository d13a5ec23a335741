#include "geometry/box3d.h"

#include <cmath>

namespace geodrive {

Rigid3d Box3d::WorldFromBox() const {
  return Rigid3d(rotation.normalized(), center);
}

Eigen::Vector3d Box3d::HalfExtents() const {
  return Eigen::Vector3d(size[1], size[0], size[2]) * 0.5;
}

bool Box3d::Contains(const Eigen::Vector3d& point_in_world,
                     double margin) const {
  const Eigen::Vector3d p =
      rotation.normalized().conjugate() * (point_in_world - center);
  const Eigen::Vector3d h = HalfExtents();
  return std::abs(p.x()) <= h.x() + margin &&
         std::abs(p.y()) <= h.y() + margin && std::abs(p.z()) <= h.z() + margin;
}

std::array<Eigen::Vector3d, 8> Box3d::Corners() const {
  const Eigen::Vector3d h = HalfExtents();
  const Rigid3d world_from_box = WorldFromBox();
  std::array<Eigen::Vector3d, 8> corners;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d c((i & 1) ? h.x() : -h.x(), (i & 2) ? h.y() : -h.y(),
                            (i & 4) ? h.z() : -h.z());
    corners[i] = world_from_box * c;
  }
  return corners;
}

bool Box3d::IsValid() const {
  return center.allFinite() && size.allFinite() && (size.array() > 0).all() &&
         rotation.coeffs().allFinite() &&
         std::abs(rotation.norm() - 1.0) <= 1e-6;
}

Box3d Box3d::Transformed(const Rigid3d& b_from_a) const {
  Box3d out = *this;
  out.center = b_from_a * center;
  out.rotation = (b_from_a.rotation * rotation).normalized();
  return out;
}

Box3d Interpolate(const Box3d& a, const Box3d& b, double t) {
  Box3d out;
  out.center = (1 - t) * a.center + t * b.center;
  out.size = (1 - t) * a.size + t * b.size;
  out.rotation = a.rotation.normalized().slerp(t, b.rotation.normalized());
  return out;
}

}  // namespace geodrive
