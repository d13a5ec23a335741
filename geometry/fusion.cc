#include "geometry/fusion.h"

#include <pcl/filters/radius_outlier_removal.h>
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include "geometry/util/status.h"

namespace geodrive {
namespace {

struct KeyIndex {
  uint64_t key;
  uint32_t index;
};

// LSD radix sort on 16-bit digits; passes whose digit is constant are skipped.
void RadixSort(std::vector<KeyIndex>* items) {
  std::vector<KeyIndex> buffer(items->size());
  std::vector<KeyIndex>* src = items;
  std::vector<KeyIndex>* dst = &buffer;
  std::vector<size_t> count(1 << 16);
  for (int shift = 0; shift < 64; shift += 16) {
    std::fill(count.begin(), count.end(), 0);
    for (const auto& it : *src) ++count[(it.key >> shift) & 0xFFFF];
    if (std::any_of(count.begin(), count.end(),
                    [&](size_t c) { return c == src->size(); })) {
      continue;
    }
    size_t sum = 0;
    for (auto& c : count) {
      const size_t tmp = c;
      c = sum;
      sum += tmp;
    }
    for (const auto& it : *src)
      (*dst)[count[(it.key >> shift) & 0xFFFF]++] = it;
    std::swap(src, dst);
  }
  if (src != items) *items = std::move(*src);
}

// Averages the points of each voxel. `provenance_in` may be empty.
void VoxelDownsample(const PointCloud& in,
                     const std::vector<PointProvenance>& provenance_in,
                     double voxel_size,
                     PointCloud* out,
                     std::vector<PointProvenance>* provenance_out) {
  const size_t n = in.size();
  GEODRIVE_CHECK_INPUT(n < (1ull << 32), "fusion: too many input points (", n,
                       ")");
  Eigen::Vector3d lo =
      Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const auto& p : in.positions) {
    lo = lo.cwiseMin(p.cast<double>());
    hi = hi.cwiseMax(p.cast<double>());
  }
  const double inv = 1.0 / voxel_size;
  lo = (lo * inv).array().floor().matrix() *
       voxel_size;  // grid aligned to multiples of the size
  // Compact keys: just enough bits per axis for the extent (fewer radix
  // passes).
  int bits[3];
  for (int k = 0; k < 3; ++k) {
    const double cells = std::floor((hi[k] - lo[k]) * inv) + 1;
    GEODRIVE_CHECK_INPUT(
        cells < static_cast<double>(1 << 21), "fusion: voxel size ", voxel_size,
        " too small for the cloud extent (more than 2^21 voxels per axis)");
    bits[k] = 1;
    while ((1ull << bits[k]) < static_cast<uint64_t>(cells)) ++bits[k];
  }
  const uint64_t max_cell[3] = {(1ull << bits[0]) - 1, (1ull << bits[1]) - 1,
                                (1ull << bits[2]) - 1};
  std::vector<KeyIndex> items(n);
  const float lox = static_cast<float>(lo.x()),
              loy = static_cast<float>(lo.y()),
              loz = static_cast<float>(lo.z()), invf = static_cast<float>(inv);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f& p = in.positions[i];
    // Clamped: float rounding at the bounds must not spill into another axis'
    // bits.
    const uint64_t cx = std::min<uint64_t>(
        static_cast<uint64_t>(std::max(0.f, (p.x() - lox) * invf)),
        max_cell[0]);
    const uint64_t cy = std::min<uint64_t>(
        static_cast<uint64_t>(std::max(0.f, (p.y() - loy) * invf)),
        max_cell[1]);
    const uint64_t cz = std::min<uint64_t>(
        static_cast<uint64_t>(std::max(0.f, (p.z() - loz) * invf)),
        max_cell[2]);
    items[i] = {(cx << (bits[1] + bits[2])) | (cy << bits[2]) | cz,
                static_cast<uint32_t>(i)};
  }
  RadixSort(&items);
  const bool colors = in.HasColors(), conf = in.HasConfidence();
  const bool prov = !provenance_in.empty() && provenance_out;
  *out = PointCloud();
  if (provenance_out) provenance_out->clear();
  for (size_t a = 0; a < n;) {
    size_t b = a + 1;
    while (b < n && items[b].key == items[a].key) ++b;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    Eigen::Vector3i rgb = Eigen::Vector3i::Zero();
    double csum = 0;
    for (size_t k = a; k < b; ++k) {
      const uint32_t i = items[k].index;
      sum += in.positions[i].cast<double>();
      if (colors) rgb += in.colors[i].cast<int>();
      if (conf) csum += in.confidence[i];
    }
    const double m = static_cast<double>(b - a);
    const Eigen::Vector3d centroid = sum / m;
    out->positions.push_back(centroid.cast<float>());
    if (colors) {
      out->colors.push_back(((rgb.cast<double>() / m).array() + 0.5)
                                .floor()
                                .cast<uint8_t>()
                                .matrix());
    }
    if (conf) out->confidence.push_back(static_cast<float>(csum / m));
    if (prov) {
      uint32_t best = items[a].index;
      double best_d = std::numeric_limits<double>::infinity();
      for (size_t k = a; k < b; ++k) {
        const double d =
            (in.positions[items[k].index].cast<double>() - centroid)
                .squaredNorm();
        if (d < best_d) best_d = d, best = items[k].index;
      }
      provenance_out->push_back(provenance_in[best]);
    }
    a = b;
  }
}

pcl::PointCloud<pcl::PointXYZ>::Ptr ToPcl(const PointCloud& cloud) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr pcl_cloud(
      new pcl::PointCloud<pcl::PointXYZ>);
  pcl_cloud->resize(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    (*pcl_cloud)[i].x = cloud.positions[i].x();
    (*pcl_cloud)[i].y = cloud.positions[i].y();
    (*pcl_cloud)[i].z = cloud.positions[i].z();
  }
  pcl_cloud->width = static_cast<uint32_t>(cloud.size());
  pcl_cloud->height = 1;
  pcl_cloud->is_dense = true;
  return pcl_cloud;
}

void KeepIndices(const pcl::Indices& kept,
                 PointCloud* cloud,
                 std::vector<PointProvenance>* provenance) {
  std::vector<size_t> idx(kept.begin(), kept.end());
  *cloud = cloud->Select(idx);
  if (provenance && !provenance->empty()) {
    std::vector<PointProvenance> p;
    p.reserve(idx.size());
    for (size_t i : idx) p.push_back((*provenance)[i]);
    *provenance = std::move(p);
  }
}

double Median(std::vector<float> v) {
  if (v.empty()) return 0;
  auto mid = v.begin() + v.size() / 2;
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

void FusionOptions::Check() const {
  GEODRIVE_CHECK_INPUT(std::isfinite(voxel_size), "voxel_size must be finite");
  GEODRIVE_CHECK_INPUT(
      std::isfinite(auto_voxel_fraction) && auto_voxel_fraction > 0,
      "auto_voxel_fraction ", auto_voxel_fraction, " must be positive");
  GEODRIVE_CHECK_INPUT(sor_mean_k >= 1 && sor_mean_k <= 1000, "sor_mean_k ",
                       sor_mean_k, " must be in [1, 1000]");
  GEODRIVE_CHECK_INPUT(std::isfinite(sor_stddev_mul) && sor_stddev_mul > 0,
                       "sor_stddev_mul ", sor_stddev_mul, " must be positive");
  GEODRIVE_CHECK_INPUT(std::isfinite(ror_radius) && ror_radius >= 0,
                       "ror_radius ", ror_radius, " must be >= 0");
  GEODRIVE_CHECK_INPUT(ror_min_neighbors >= 1, "ror_min_neighbors ",
                       ror_min_neighbors, " must be >= 1");
}

std::string FusionSummary::ToString() const {
  std::ostringstream os;
  os << "frames " << num_frames << "; " << filter.ToString() << "; points "
     << input_points << " -> voxel (" << voxel_size << ") " << after_voxel
     << " -> statistical " << after_statistical << " -> radius " << after_radius
     << "; " << seconds << " s";
  return os.str();
}

FusedCloud FuseCloud(const PointCloud& cloud,
                     const std::vector<PointProvenance>* provenance,
                     const std::vector<float>* depths,
                     const FusionOptions& options) {
  options.Check();
  cloud.Check("fusion input");
  GEODRIVE_CHECK_INPUT(!provenance || provenance->size() == cloud.size(),
                       "fusion: provenance size differs from the cloud");
  const auto start = std::chrono::steady_clock::now();
  FusedCloud out;
  out.summary.input_points = static_cast<int64_t>(cloud.size());
  double voxel = options.voxel_size;
  if (voxel == 0) {
    voxel = depths && !depths->empty()
                ? options.auto_voxel_fraction * Median(*depths)
                : -1;
  }
  const std::vector<PointProvenance> empty;
  const std::vector<PointProvenance>& prov_in =
      options.keep_provenance && provenance ? *provenance : empty;
  if (voxel > 0 && !cloud.empty()) {
    VoxelDownsample(cloud, prov_in, voxel, &out.cloud, &out.provenance);
    out.summary.voxel_size = voxel;
  } else {
    out.cloud = cloud;
    out.provenance = prov_in;
  }
  out.summary.after_voxel = static_cast<int64_t>(out.cloud.size());

  if (options.statistical_outlier_removal &&
      out.cloud.size() > static_cast<size_t>(options.sor_mean_k + 1)) {
    pcl::StatisticalOutlierRemoval<pcl::PointXYZ>
        sor;  // k-d tree: pcl::search::KdTree (FLANN)
    sor.setInputCloud(ToPcl(out.cloud));
    sor.setMeanK(options.sor_mean_k);
    sor.setStddevMulThresh(options.sor_stddev_mul);
    pcl::Indices kept;
    sor.filter(kept);
    KeepIndices(kept, &out.cloud, &out.provenance);
  }
  out.summary.after_statistical = static_cast<int64_t>(out.cloud.size());

  if (options.radius_outlier_removal && !out.cloud.empty()) {
    double radius = options.ror_radius;
    if (radius == 0) radius = 3 * std::max(voxel, 0.0);
    GEODRIVE_CHECK_INPUT(
        radius > 0,
        "fusion: radius outlier removal needs ror_radius (no voxel "
        "size to derive it from)");
    pcl::RadiusOutlierRemoval<pcl::PointXYZ> ror;
    ror.setInputCloud(ToPcl(out.cloud));
    ror.setRadiusSearch(radius);
    ror.setMinNeighborsInRadius(options.ror_min_neighbors);
    pcl::Indices kept;
    ror.filter(kept);
    KeepIndices(kept, &out.cloud, &out.provenance);
  }
  out.summary.after_radius = static_cast<int64_t>(out.cloud.size());
  out.summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  return out;
}

FusedCloud FusePointmaps(const std::vector<Pointmap>& pointmaps,
                         const PointmapFilterOptions& filter,
                         const FusionOptions& options) {
  filter.Check();
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  PointCloud all;
  std::vector<PointProvenance> provenance;
  std::vector<float> depths;
  PointmapFilterStats stats;
  bool colors = !pointmaps.empty(), conf = !pointmaps.empty();
  for (const auto& pm : pointmaps)
    colors &= !pm.rgb.empty(), conf &= !pm.confidence.empty();
  for (const auto& pm : pointmaps) {
    PointmapFilterStats s;
    const cv::Mat valid = ComputeValidMask(pm, filter, &s);
    stats.Add(s);
    std::vector<PointProvenance> prov;
    std::vector<float> d;
    PointCloud c =
        ExtractPoints(pm, valid, options.keep_provenance ? &prov : nullptr, &d);
    if (!colors) c.colors.clear();
    if (!conf) c.confidence.clear();
    if (all.empty()) {
      all = std::move(c);
    } else {
      all.positions.insert(all.positions.end(), c.positions.begin(),
                           c.positions.end());
      all.colors.insert(all.colors.end(), c.colors.begin(), c.colors.end());
      all.confidence.insert(all.confidence.end(), c.confidence.begin(),
                            c.confidence.end());
    }
    provenance.insert(provenance.end(), prov.begin(), prov.end());
    depths.insert(depths.end(), d.begin(), d.end());
  }
  FusedCloud out = FuseCloud(
      all, options.keep_provenance ? &provenance : nullptr, &depths, options);
  out.summary.num_frames = static_cast<int>(pointmaps.size());
  out.summary.filter = stats;
  out.summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  return out;
}

}  // namespace geodrive
