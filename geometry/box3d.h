#pragma once
// The one oriented 3D box type of the toolkit (nuScenes convention) and its
// point-in-box test. Dataset adapters convert their own box records to it
// (e.g. NuscenesBox at the nuScenes adapter); the editor, the LiDAR scene
// source and the boxes file speak only Box3d.
//
// Convention: `center` in the frame the box is expressed in (world, camera 0,
// ...), `size` = [width, length, height], `rotation` = frame_from_box. The box
// frame has x forward (along the length), y left (along the width), z up.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>

#include "geometry/rigid3.h"

namespace geodrive {

struct Box3d {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  // world frame
  Eigen::Vector3d size = Eigen::Vector3d::Zero();    // [w, l, h]
  Eigen::Quaterniond rotation =
      Eigen::Quaterniond::Identity();  // world_from_box

  // world_from_box (box frame: x forward = length, y left = width, z up =
  // height).
  Rigid3d WorldFromBox() const;
  // Half extents along the box axes (x, y, z) = (l / 2, w / 2, h / 2).
  Eigen::Vector3d HalfExtents() const;
  // True if the world point lies inside the box grown by `margin` (same units)
  // on every side: |R^T (p - c)| <= half extents + margin, per axis.
  bool Contains(const Eigen::Vector3d& point_in_world,
                double margin = 0.0) const;
  // The 8 corners in the world frame.
  std::array<Eigen::Vector3d, 8> Corners() const;
  bool IsValid() const;  // finite, size > 0, unit quaternion (1e-6)
  // The box expressed in frame b: center' = b_from_a * center,
  // rotation' = normalize(R_b_from_a * rotation).
  Box3d Transformed(const Rigid3d& b_from_a) const;
};

// Interpolates two boxes: lerp of centre and size, slerp of rotation; t in [0,
// 1].
Box3d Interpolate(const Box3d& a, const Box3d& b, double t);

}  // namespace geodrive
