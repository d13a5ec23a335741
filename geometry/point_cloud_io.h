#pragma once
// Point cloud files: PLY and PCD (through PCL io), nuScenes LIDAR_TOP
// `.pcd.bin` and KITTI velodyne `.bin`. Every failure throws InputError naming
// the file.

#include <string>

#include "geometry/point_cloud.h"

namespace geodrive {

// nuScenes `.pcd.bin`: little-endian float32 x 5 per point (x, y, z, intensity,
// ring), LIDAR_TOP frame (x right, y forward, z up). Fills positions, intensity
// and ring. The file size must be a multiple of 20 bytes.
PointCloud ReadNuscenesLidarBin(const std::string& path);
void WriteNuscenesLidarBin(const std::string& path, const PointCloud& cloud);

// KITTI velodyne `.bin`: float32 x 4 (x, y, z, reflectance), x forward, y left,
// z up. Fills positions and intensity. The file size must be a multiple of 16
// bytes.
PointCloud ReadKittiVelodyneBin(const std::string& path);
// Writes float32 x 4 (intensity 0 where the cloud has none).
void WriteKittiVelodyneBin(const std::string& path, const PointCloud& cloud);

// PLY (binary little-endian on write; ASCII or binary on read) with x y z,
// optional red green blue, and the optional scalar properties `confidence`,
// `instance_id`, `intensity`.
PointCloud ReadPly(const std::string& path);
void WritePly(const std::string& path,
              const PointCloud& cloud,
              bool binary = true);

// PCD (PCL's format) with x y z and optional rgb / intensity (plus confidence,
// instance_id and ring when present). Points with non-finite coordinates
// (organised-cloud holes) are dropped.
PointCloud ReadPcd(const std::string& path);
void WritePcd(const std::string& path,
              const PointCloud& cloud,
              bool binary = true);

// Dispatch on extension (case-insensitive): .ply, .pcd, .pcd.bin (nuScenes),
// .bin (KITTI). Writes are atomic (temporary file + rename).
PointCloud ReadPointCloud(const std::string& path);
void WritePointCloud(const std::string& path, const PointCloud& cloud);

}  // namespace geodrive
