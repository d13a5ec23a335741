#pragma once
// The one place that converts between geodrive::PointCloud and PCL types
// (internal to geodrive_geometry; PCL never appears in public headers).
//
// Colours: PCL packs RGB into a uint32 0x00RRGGBB stored in the `rgb` float
// field (or `rgba`). Intensity maps to PointXYZI::intensity. Non-finite PCL
// points (organised-cloud holes) are dropped by the FromPcl* functions.

#include <pcl/PCLPointCloud2.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <string>

#include "geometry/point_cloud.h"

namespace geodrive {
namespace internal {

// Typed conversions. Missing attributes become zero (colour black, intensity
// 0).
pcl::PointCloud<pcl::PointXYZ>::Ptr ToPclXyz(const PointCloud& cloud);
pcl::PointCloud<pcl::PointXYZRGB>::Ptr ToPclXyzRgb(const PointCloud& cloud);
pcl::PointCloud<pcl::PointXYZI>::Ptr ToPclXyzI(const PointCloud& cloud);
PointCloud FromPcl(const pcl::PointCloud<pcl::PointXYZ>& cloud);
PointCloud FromPcl(const pcl::PointCloud<pcl::PointXYZRGB>& cloud);
PointCloud FromPcl(const pcl::PointCloud<pcl::PointXYZI>& cloud);

// Field-preserving conversion: x y z (float32) plus whichever of rgb (packed
// float32), intensity (float32), confidence (float32), instance_id (int32),
// ring (float32) the cloud has.
pcl::PCLPointCloud2 ToPclPointCloud2(const PointCloud& cloud);
// Reads x y z (required; any numeric type) and the optional fields above (any
// numeric type; colour from `rgb`/`rgba` or separate `red`/`green`/`blue`).
// Throws InputError naming `what` if x, y or z is missing or the data is
// inconsistent with the field layout.
PointCloud FromPclPointCloud2(const pcl::PCLPointCloud2& cloud,
                              const std::string& what);

// Silences PCL's console output (errors are reported through InputError
// instead) for the lifetime of the guard.
class PclQuietGuard {
 public:
  PclQuietGuard();
  ~PclQuietGuard();
  PclQuietGuard(const PclQuietGuard&) = delete;
  PclQuietGuard& operator=(const PclQuietGuard&) = delete;

 private:
  int previous_level_;
};

}  // namespace internal
}  // namespace geodrive
