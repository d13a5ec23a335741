#pragma once
// A plain point cloud: positions plus optional parallel attributes. No algorithms live here
// (they are free functions elsewhere); conversion to PCL happens in geometry/internal only.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace geodrive {

using Color3u8 = Eigen::Matrix<uint8_t, 3, 1>;  // RGB, 0..255

// 1 when f is NaN or +-Inf (its exponent bits are all ones), else 0: a
// branch-free test that vectorises, for scans over many values.
inline uint32_t NotFiniteBit(float f) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return static_cast<uint32_t>((u & 0x7f800000u) == 0x7f800000u);
}

struct PointCloud {
  // Point positions; the frame is the caller's (name the variable: points_in_world, ...).
  std::vector<Eigen::Vector3f> positions;
  // Optional attributes: empty, or exactly one entry per point.
  std::vector<Color3u8> colors;         // RGB
  std::vector<float> confidence;        // in [0, 1] unless documented otherwise
  std::vector<int32_t> instance_ids;    // -1 = background / static
  std::vector<float> intensity;         // LiDAR return intensity (nuScenes: 0..255)
  std::vector<float> ring;              // LiDAR ring index (nuScenes: 0..31)
  // Capture footprint: the side, in the cloud's units, of the pixel that saw
  // the point (capture depth / focal length in pixels; 0 = unknown).
  // Footprint-aware splats (render/footprint.h) draw a point seen from closer
  // than at capture over the area it covers.
  std::vector<float> footprints;
  // Optional, with footprints: the capture pixel as a surface patch, the
  // surface's displacement per capture pixel along x and y (in the cloud's
  // frame; zero = unknown, then the square of side `footprints` is used).
  std::vector<Eigen::Vector3f> footprint_u, footprint_v;

  size_t size() const { return positions.size(); }
  bool empty() const { return positions.empty(); }
  bool HasColors() const { return !colors.empty(); }
  bool HasConfidence() const { return !confidence.empty(); }
  bool HasInstanceIds() const { return !instance_ids.empty(); }
  bool HasIntensity() const { return !intensity.empty(); }
  bool HasRing() const { return !ring.empty(); }
  bool HasFootprints() const { return !footprints.empty(); }

  void Reserve(size_t n);
  // Throws InputError naming `what` if an attribute's size differs from size() or a position is
  // not finite.
  void Check(const std::string& what = "point cloud") const;
  // Check without the scan of the positions, for callers that test them as
  // they copy them (and call Check for the message when one is not finite).
  void CheckAttributes(const std::string& what = "point cloud") const;
  // Whether every coordinate is finite: a branch-free scan that vectorises
  // (the readers' NaN policy and Check run it before any per-point loop).
  bool AllPositionsFinite() const;
  // Axis-aligned bounds of the finite positions (empty box for an empty cloud).
  Eigen::AlignedBox3f Bounds() const;
  // Appends `other`; attributes present in only one of the clouds are dropped from the result.
  void Append(const PointCloud& other);
  // Keeps the points whose index is in `indices` (in that order), with all attributes.
  PointCloud Select(const std::vector<size_t>& indices) const;
};

}  // namespace geodrive
