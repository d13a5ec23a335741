#include "geometry/internal/pcl_adapter.h"

#include <pcl/console/print.h>

#include <cmath>

namespace geodrive {
namespace internal {
namespace {

bool Finite(float x, float y, float z) {
  return std::isfinite(x) && std::isfinite(y) && std::isfinite(z);
}

template <typename PointT>
typename pcl::PointCloud<PointT>::Ptr MakeCloud(const PointCloud& cloud) {
  auto out = std::make_shared<pcl::PointCloud<PointT>>();
  out->resize(cloud.size());
  out->width = static_cast<uint32_t>(cloud.size());
  out->height = 1;
  out->is_dense = true;
  for (size_t i = 0; i < cloud.size(); ++i) {
    PointT& p = (*out)[i];
    p.x = cloud.positions[i].x();
    p.y = cloud.positions[i].y();
    p.z = cloud.positions[i].z();
    if (!Finite(p.x, p.y, p.z)) out->is_dense = false;
  }
  return out;
}

}  // namespace

pcl::PointCloud<pcl::PointXYZ>::Ptr ToPclXyz(const PointCloud& cloud) {
  return MakeCloud<pcl::PointXYZ>(cloud);
}

pcl::PointCloud<pcl::PointXYZRGB>::Ptr ToPclXyzRgb(const PointCloud& cloud) {
  auto out = MakeCloud<pcl::PointXYZRGB>(cloud);
  for (size_t i = 0; i < cloud.size(); ++i) {
    pcl::PointXYZRGB& p = (*out)[i];
    const Color3u8 c = cloud.HasColors() ? cloud.colors[i] : Color3u8(0, 0, 0);
    p.r = c[0];
    p.g = c[1];
    p.b = c[2];
    p.a = 255;
  }
  return out;
}

pcl::PointCloud<pcl::PointXYZI>::Ptr ToPclXyzI(const PointCloud& cloud) {
  auto out = MakeCloud<pcl::PointXYZI>(cloud);
  for (size_t i = 0; i < cloud.size(); ++i) {
    (*out)[i].intensity = cloud.HasIntensity() ? cloud.intensity[i] : 0.f;
  }
  return out;
}

PointCloud FromPcl(const pcl::PointCloud<pcl::PointXYZ>& cloud) {
  PointCloud out;
  out.Reserve(cloud.size());
  for (const auto& p : cloud) {
    if (Finite(p.x, p.y, p.z)) out.positions.emplace_back(p.x, p.y, p.z);
  }
  return out;
}

PointCloud FromPcl(const pcl::PointCloud<pcl::PointXYZRGB>& cloud) {
  PointCloud out;
  out.Reserve(cloud.size());
  for (const auto& p : cloud) {
    if (!Finite(p.x, p.y, p.z)) continue;
    out.positions.emplace_back(p.x, p.y, p.z);
    out.colors.emplace_back(p.r, p.g, p.b);
  }
  return out;
}

PointCloud FromPcl(const pcl::PointCloud<pcl::PointXYZI>& cloud) {
  PointCloud out;
  out.Reserve(cloud.size());
  for (const auto& p : cloud) {
    if (!Finite(p.x, p.y, p.z)) continue;
    out.positions.emplace_back(p.x, p.y, p.z);
    out.intensity.push_back(p.intensity);
  }
  return out;
}

PclQuietGuard::PclQuietGuard()
    : previous_level_(pcl::console::getVerbosityLevel()) {
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
}

PclQuietGuard::~PclQuietGuard() {
  pcl::console::setVerbosityLevel(
      static_cast<pcl::console::VERBOSITY_LEVEL>(previous_level_));
}

}  // namespace internal
}  // namespace geodrive
