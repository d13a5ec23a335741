#pragma once
// Fusion of filtered pointmaps into one coloured world cloud: voxel-grid
// downsampling with colour/confidence averaging, then statistical (and
// optionally radius) outlier removal through PCL's FLANN k-d tree. Provenance
// (frame, pixel) is kept per output point when asked.

#include <cstdint>
#include <string>
#include <vector>

#include "geometry/point_cloud.h"
#include "geometry/pointmap.h"

namespace geodrive {

struct FusionOptions {
  // Voxel edge length in cloud units (metres once scaled, else MonST3R units).
  // 0 = automatic: auto_voxel_fraction x the median camera depth of the input
  // points. < 0 = no downsampling.
  double voxel_size = 0.0;
  double auto_voxel_fraction = 0.02;
  // Statistical outlier removal (PCL): drop points whose mean distance to their
  // sor_mean_k nearest neighbours exceeds mean + sor_stddev_mul * stddev over
  // the cloud.
  bool statistical_outlier_removal = true;
  int sor_mean_k = 8;
  double sor_stddev_mul = 2.0;
  // Radius outlier removal (PCL): drop points with fewer than ror_min_neighbors
  // neighbours within ror_radius (cloud units; 0 = 3 x the voxel size used).
  bool radius_outlier_removal = false;
  double ror_radius = 0.0;
  int ror_min_neighbors = 4;
  // Keep one (frame, pixel) per output point: the input point nearest its
  // voxel's centroid.
  bool keep_provenance = false;

  // Throws InputError naming the bad field.
  void Check() const;
};

struct FusionSummary {
  int num_frames = 0;
  PointmapFilterStats filter;  // per-pixel filter counts (FusePointmaps only)
  int64_t input_points = 0;
  int64_t after_voxel = 0;
  int64_t after_statistical = 0;
  int64_t after_radius = 0;
  double voxel_size = 0;  // the size used (0 = none)
  double seconds = 0;
  std::string ToString() const;
};

struct FusedCloud {
  PointCloud cloud;  // world positions, colours, mean confidence
  std::vector<PointProvenance>
      provenance;  // parallel to cloud when keep_provenance
  FusionSummary summary;
};

// Filters each pointmap (ComputeValidMask) and fuses the kept points.
FusedCloud FusePointmaps(const std::vector<Pointmap>& pointmaps,
                         const PointmapFilterOptions& filter,
                         const FusionOptions& options);

// Downsamples and cleans an existing cloud. `provenance` (may be null) is
// parallel to `cloud`; `depths` (may be null) are the camera depths used for
// the automatic voxel size (without them an automatic voxel size means no
// downsampling).
FusedCloud FuseCloud(const PointCloud& cloud,
                     const std::vector<PointProvenance>* provenance,
                     const std::vector<float>* depths,
                     const FusionOptions& options);

}  // namespace geodrive
