#pragma once
// The one place that converts between geodrive::PointCloud and PCL types
// (internal to geodrive_geometry; PCL never appears in public headers).
//
// Colours: PCL packs RGB into a uint32 0x00RRGGBB stored in the `rgb` float
// field. Intensity maps to PointXYZI::intensity. Non-finite PCL points
// (organised-cloud holes) are dropped by the FromPcl* functions. Point cloud
// files do not go through PCL (geometry/point_cloud_io.cc).

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
