// Dynamic editing, 3D mode: the frame-0 segmentation of each instance (the
// points of its 3D box, or of its 2D box above the ground, on the dynamic
// mask and in the dominant depth cluster), with the frame-0 projection and the
// one-pass points-in-boxes search it uses.

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>

#include "render/dynamic_edit.h"
#include "render/internal/dynamic_edit_internal.h"

namespace geodrive {
namespace dynamic_edit_internal {
namespace {

// For each box, the indices (ascending) of the points inside it. One pass
// over the points: a coarse grid over the boxes' bounding region (x, y) holds
// per cell a bit mask of the boxes whose bounding box overlaps it, so a point
// far from every box costs a few compares and only points in marked cells get
// the exact tests. Boxes are taken 64 at a time (one mask bit each).
std::vector<std::vector<size_t>> PointsInBoxes(
    const std::vector<Eigen::Vector3f>& positions,
    const std::vector<FastBox>& boxes,
    int num_threads) {
  std::vector<std::vector<size_t>> inside(boxes.size());
  constexpr int kGrid = 64;
  for (size_t first = 0; first < boxes.size(); first += 64) {
    const size_t last = std::min(boxes.size(), first + 64);
    // World-axis-aligned bounding box of each box, and their union.
    std::vector<Eigen::Vector3f> lo(last - first), hi(last - first);
    Eigen::Vector3f ulo = Eigen::Vector3f::Constant(
                        std::numeric_limits<float>::infinity()),
                    uhi = -ulo;
    for (size_t k = first; k < last; ++k) {
      lo[k - first] = boxes[k].center - boxes[k].extent;
      hi[k - first] = boxes[k].center + boxes[k].extent;
      ulo = ulo.cwiseMin(lo[k - first]);
      uhi = uhi.cwiseMax(hi[k - first]);
    }
    // Cell of a coordinate; monotonic in it, so a point inside a bounding box
    // falls in one of that box's cells.
    const float sx = kGrid / std::max(uhi.x() - ulo.x(), 1e-6f);
    const float sy = kGrid / std::max(uhi.y() - ulo.y(), 1e-6f);
    auto cell = [](float c, float origin, float scale) {
      return std::clamp(static_cast<int>((c - origin) * scale), 0, kGrid - 1);
    };
    std::vector<uint64_t> mask(kGrid * kGrid, 0);
    for (size_t k = first; k < last; ++k) {
      const size_t j = k - first;
      const int x0 = cell(lo[j].x(), ulo.x(), sx),
                x1 = cell(hi[j].x(), ulo.x(), sx);
      const int y0 = cell(lo[j].y(), ulo.y(), sy),
                y1 = cell(hi[j].y(), ulo.y(), sy);
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) mask[y * kGrid + x] |= uint64_t{1} << j;
    }
    // Contiguous chunks of points per thread, merged in chunk order (so the
    // lists stay ascending whatever the thread count).
    const size_t n = positions.size();
    const int chunks = static_cast<int>(
        std::clamp<size_t>(n / 32768, 1, std::max(1, num_threads)));
    std::vector<std::vector<std::vector<size_t>>> found(
        chunks, std::vector<std::vector<size_t>>(last - first));
#pragma omp parallel for num_threads(chunks) schedule(static, 1)
    for (int c = 0; c < chunks; ++c) {
      const size_t begin = n * c / chunks, end = n * (c + 1) / chunks;
      for (size_t i = begin; i < end; ++i) {
        const Eigen::Vector3f& p = positions[i];
        if (!(p.x() >= ulo.x() && p.x() <= uhi.x() && p.y() >= ulo.y() &&
              p.y() <= uhi.y() && p.z() >= ulo.z() && p.z() <= uhi.z()))
          continue;
        uint64_t m =
            mask[cell(p.y(), ulo.y(), sy) * kGrid + cell(p.x(), ulo.x(), sx)];
        while (m) {
          const int j = __builtin_ctzll(m);
          m &= m - 1;
          if (boxes[first + j].Contains(p)) found[c][j].push_back(i);
        }
      }
    }
    for (size_t j = 0; j < last - first; ++j)
      for (int c = 0; c < chunks; ++c)
        inside[first + j].insert(inside[first + j].end(), found[c][j].begin(),
                                 found[c][j].end());
  }
  return inside;
}

// True without a plane, or when `p` is more than `ground_margin` above it.
bool AboveGround(const std::optional<Eigen::Vector4d>& plane,
                 const Eigen::Vector3f& p,
                 double ground_margin) {
  return !plane || PlaneDistance(*plane, p.cast<double>()) > ground_margin;
}

// The points of a frame-0 3D box (`in_box`: those inside it) not taken by an
// earlier instance and not road.
std::vector<size_t> PointsOf3dBox(const PointCloud& cloud_in_world,
                                  const FastBox& fast,
                                  const std::vector<size_t>& in_box,
                                  const std::vector<char>& taken,
                                  const std::optional<Eigen::Vector4d>& plane,
                                  const DynamicEditOptions& options) {
  std::vector<size_t> indices;
  const float margin = static_cast<float>(options.ground_margin);
  for (size_t i : in_box) {
    if (taken[i]) continue;
    // Road points: near the ground plane, or without one, near the box's
    // bottom face.
    if (plane ? AboveGround(plane, cloud_in_world.positions[i],
                            options.ground_margin)
              : fast.HeightAboveBottom(cloud_in_world.positions[i]) > margin)
      indices.push_back(i);
  }
  return indices;
}

// Keeps the candidates whose frame-0 pixel is on options.dynamic_mask, unless
// that leaves fewer than options.min_object_points (then a note).
void KeepDynamicMaskPoints(const PinholeCamera& camera0,
                           const Frame0Projection& proj,
                           const DynamicEditOptions& options,
                           const std::string& id,
                           DynamicEditSummary* summary,
                           std::vector<size_t>* cand) {
  std::vector<size_t> dyn;
  const double mx = double(options.dynamic_mask.cols) / camera0.width;
  const double my = double(options.dynamic_mask.rows) / camera0.height;
  for (size_t i : *cand) {
    const int mu =
        std::min(options.dynamic_mask.cols - 1, int((proj.u[i] + 0.5) * mx));
    const int mv =
        std::min(options.dynamic_mask.rows - 1, int((proj.v[i] + 0.5) * my));
    if (options.dynamic_mask.at<uint8_t>(mv, mu)) dyn.push_back(i);
  }
  if (static_cast<int>(dyn.size()) >= options.min_object_points) {
    cand->swap(dyn);
  } else {
    AddNote(summary, id, 0,
            "dynamic mask leaves too few points in the box; ignored");
  }
}

// Dominant depth cluster: the candidates sorted by frame-0 depth are split
// where consecutive depths differ by more than depth_gap_abs + depth_gap_rel *
// depth; returns the largest cluster (in depth order).
std::vector<size_t> DominantDepthCluster(std::vector<size_t> cand,
                                         const Frame0Projection& proj,
                                         const DynamicEditOptions& options) {
  std::sort(cand.begin(), cand.end(), [&](size_t a, size_t b) {
    return proj.z[a] < proj.z[b] || (proj.z[a] == proj.z[b] && a < b);
  });
  size_t best_begin = 0, best_end = 0, begin = 0;
  for (size_t k2 = 1; k2 <= cand.size(); ++k2) {
    const bool split = k2 == cand.size() ||
                       proj.z[cand[k2]] - proj.z[cand[k2 - 1]] >
                           options.depth_gap_abs +
                               options.depth_gap_rel * proj.z[cand[k2 - 1]];
    if (split) {
      if (k2 - begin > best_end - best_begin) {
        best_begin = begin;
        best_end = k2;
      }
      begin = k2;
    }
  }
  return std::vector<size_t>(cand.begin() + best_begin,
                             cand.begin() + best_end);
}

// Segments an instance by its frame-0 pixel box `box`: the points projecting
// into it, not taken, above the ground, on the dynamic mask, in the dominant
// depth cluster; sets seg->indices (ascending), seg->lift.box0 and the median
// depth seg->lift.depth0.
void SegmentBy2dBox(const PointCloud& cloud_in_world,
                    const Box2d& box,
                    const PinholeCamera& camera0,
                    const Frame0Projection& proj,
                    const std::vector<char>& taken,
                    const std::optional<Eigen::Vector4d>& plane,
                    const DynamicEditOptions& options,
                    const std::string& id,
                    DynamicEditSummary* summary,
                    Segment* seg) {
  const size_t n = cloud_in_world.size();
  const cv::Rect w = PixelWindow(box, camera0.width, camera0.height);
  std::vector<size_t> cand;
  for (size_t i = 0; i < n; ++i) {
    if (taken[i] || proj.u[i] < 0 || !InWindow(w, proj.u[i], proj.v[i]) ||
        !AboveGround(plane, cloud_in_world.positions[i], options.ground_margin))
      continue;
    cand.push_back(i);
  }
  if (!options.dynamic_mask.empty())
    KeepDynamicMaskPoints(camera0, proj, options, id, summary, &cand);
  seg->indices = DominantDepthCluster(std::move(cand), proj, options);
  std::sort(seg->indices.begin(), seg->indices.end());
  seg->lift.box0 = box;
  if (!seg->indices.empty()) {
    std::vector<float> depths;
    for (size_t i : seg->indices) depths.push_back(proj.z[i]);
    std::nth_element(depths.begin(), depths.begin() + depths.size() / 2,
                     depths.end());
    seg->lift.depth0 = depths[depths.size() / 2];
  }
}

// Lift reference (used when a frame has only a 2D box, which is what
// need_plane says).
void SetLiftReference(const PointCloud& cloud_in_world,
                      const PinholeCamera& camera0,
                      const Rigid3d& pose0,
                      const BoxSequences& boxes,
                      const Track& t,
                      const std::optional<Eigen::Vector4d>& plane,
                      bool need_plane,
                      Segment* seg) {
  if (seg->box0 && need_plane) {
    const std::optional<Box2d> b = PixelBox(t, 0, boxes, camera0, pose0);
    if (b) seg->lift.box0 = *b;
    // Camera-0 z: the third row of cam_from_world.
    const Eigen::Vector3d zrow =
        pose0.rotation.toRotationMatrix().row(2).transpose();
    const double tz = pose0.translation.z();
    std::vector<double> depths;
    depths.reserve(seg->indices.size());
    for (size_t i : seg->indices)
      depths.push_back(zrow.dot(cloud_in_world.positions[i].cast<double>()) +
                       tz);
    std::nth_element(depths.begin(), depths.begin() + depths.size() / 2,
                     depths.end());
    seg->lift.depth0 = depths[depths.size() / 2];
  }
  if (plane && seg->lift.box0.height() > 0) {
    seg->lift.ground0 = GroundHit(
        camera0, pose0,
        Eigen::Vector2d(0.5 * (seg->lift.box0.xmin + seg->lift.box0.xmax),
                        seg->lift.box0.ymax),
        *plane);
  }
}

}  // namespace

// Frame-0 pixel (rounded) and depth of every point, in camera 0 at its own
// size.
Frame0Projection ProjectFrame0(const PointCloud& cloud,
                               const PinholeCamera& camera,
                               const Rigid3d& cam_from_world) {
  Frame0Projection p;
  const size_t n = cloud.size();
  p.u.assign(n, -1);
  p.v.assign(n, -1);
  p.z.assign(n, 0.f);
  const Eigen::Matrix3f r =
      cam_from_world.rotation.normalized().toRotationMatrix().cast<float>();
  const Eigen::Vector3f t = cam_from_world.translation.cast<float>();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f q = r * cloud.positions[i] + t;
    if (!(q.z() > 0)) continue;
    const double u = camera.fx * q.x() / q.z() + camera.cx;
    const double v = camera.fy * q.y() / q.z() + camera.cy;
    const double ui = std::floor(u + 0.5), vi = std::floor(v + 0.5);
    if (ui < 0 || vi < 0 || ui >= camera.width || vi >= camera.height) continue;
    p.u[i] = static_cast<int>(ui);
    p.v[i] = static_cast<int>(vi);
    p.z[i] = q.z();
  }
  return p;
}

Segmentation SegmentInstances(const PointCloud& cloud_in_world,
                              const PinholeCamera& camera0,
                              const Rigid3d& pose0,
                              const BoxSequences& boxes,
                              const std::vector<Track>& tracks,
                              const Frame0Projection& proj,
                              const std::optional<Eigen::Vector4d>& plane,
                              bool need_plane,
                              const DynamicEditOptions& options,
                              DynamicEditSummary* summary) {
  const size_t n = cloud_in_world.size();
  // Segment every instance in frame 0. Points inside the frame-0 3D boxes,
  // all boxes in one pass.
  std::vector<FastBox> fast_boxes;
  std::vector<int> fast_box_of(boxes.instances.size(), -1);
  for (size_t k = 0; k < boxes.instances.size(); ++k) {
    if (!tracks[k].box_3d[0]) continue;
    fast_box_of[k] = static_cast<int>(fast_boxes.size());
    fast_boxes.emplace_back(*tracks[k].box_3d[0], options.box_margin);
  }
  const std::vector<std::vector<size_t>> in_box = PointsInBoxes(
      cloud_in_world.positions, fast_boxes,
      options.num_threads > 0 ? options.num_threads : omp_get_max_threads());
  std::vector<char> taken(n, 0);
  Segmentation result;
  result.segments.resize(boxes.instances.size());
  for (size_t k = 0; k < boxes.instances.size(); ++k) {
    const BoxSequence& s = boxes.instances[k];
    const Track& t = tracks[k];
    if (!t.box_3d[0] && !t.box_2d[0]) {
      AddNote(summary, s.id, 0,
              "no box in frame 0: its points cannot be found; left static");
      continue;
    }
    Segment seg;
    if (t.box_3d[0]) {
      seg.box0 = *t.box_3d[0];
      seg.indices =
          PointsOf3dBox(cloud_in_world, fast_boxes[fast_box_of[k]],
                        in_box[fast_box_of[k]], taken, plane, options);
    } else {
      const Box2d box = *PixelBox(t, 0, boxes, camera0, pose0);
      SegmentBy2dBox(cloud_in_world, box, camera0, proj, taken, plane, options,
                     s.id, summary, &seg);
    }
    if (static_cast<int>(seg.indices.size()) < options.min_object_points) {
      AddNote(summary, s.id, 0,
              "only " + std::to_string(seg.indices.size()) +
                  " point(s) segmented in frame 0 (min " +
                  std::to_string(options.min_object_points) + "); left static");
      continue;
    }
    SetLiftReference(cloud_in_world, camera0, pose0, boxes, t, plane,
                     need_plane, &seg);
    for (size_t i : seg.indices) taken[i] = 1;
    result.segments[k] = std::move(seg);
  }

  // Background: everything not segmented.
  for (size_t i = 0; i < n; ++i)
    if (taken[i]) result.hidden.push_back(i);
  return result;
}

}  // namespace dynamic_edit_internal
}  // namespace geodrive
