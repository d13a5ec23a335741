#include "dataset/drive_clip.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "geometry/util/status.h"

namespace geodrive {

std::string ToString(ClipFrameSource source) {
  return source == ClipFrameSource::kKeyframes ? "keyframes" : "all";
}

ClipFrameSource ParseClipFrameSource(const std::string& text) {
  if (text == "all") return ClipFrameSource::kAll;
  if (text == "keyframes") return ClipFrameSource::kKeyframes;
  ThrowInputError("--frames", "'", text, "' is not one of all, keyframes");
}

double DriveClip::FrameIntervalSeconds() const {
  if (frames.size() < 2) return 0;
  std::vector<int64_t> dt;
  for (size_t i = 1; i < frames.size(); ++i)
    dt.push_back(frames[i].timestamp_us - frames[i - 1].timestamp_us);
  std::nth_element(dt.begin(), dt.begin() + dt.size() / 2, dt.end());
  return dt[dt.size() / 2] * 1e-6;
}

DriveClip DriveClip::View(int k) const {
  GEODRIVE_CHECK_INPUT(k >= 0 && k < num_views(), id, ": no view ", k, " (",
                       num_views(), " cameras)");
  DriveClip view = *this;
  view.rig.clear();
  if (!rig.empty()) {
    view.channel = rig[k].channel;
    view.frames = rig[k].frames;
  }
  return view;
}

std::shared_ptr<const std::vector<Eigen::Vector3d>>
LidarProvider::StaticInWorld(size_t index) const {
  const LidarSweepInfo& info = Sweeps().at(index);
  const PointCloud sweep = Load(index);
  // [R | t]: one matrix product per point instead of a quaternion rotation.
  const Matrix3x4d world_from_lidar = info.WorldFromSensor().ToMatrix3x4();
  const std::vector<ClipBox> boxes = Boxes(index);
  // Each box's bounding sphere (grown by the margin): the exact test runs
  // only for points inside it.
  std::vector<double> radius2(boxes.size());
  for (size_t b = 0; b < boxes.size(); ++b) {
    const double r =
        boxes[b].box.HalfExtents().norm() + kBoxMarginM * std::sqrt(3.0);
    radius2[b] = r * r;
  }
  auto out = std::make_shared<std::vector<Eigen::Vector3d>>();
  out->reserve(sweep.size());
  for (size_t i = 0; i < sweep.size(); ++i) {
    const Eigen::Vector3d p = sweep.positions[i].cast<double>();
    if (p.head<2>().norm() < kEgoReturnRadiusM) continue;
    const Eigen::Vector3d g =
        world_from_lidar.leftCols<3>() * p + world_from_lidar.col(3);
    bool in_box = false;
    for (size_t b = 0; b < boxes.size() && !in_box; ++b) {
      in_box = (g - boxes[b].box.center).squaredNorm() <= radius2[b] &&
               boxes[b].box.Contains(g, kBoxMarginM);
    }
    if (!in_box) out->push_back(g);
  }
  return out;
}

std::vector<size_t> LidarProvider::SweepsBetween(int64_t lo_us,
                                                 int64_t hi_us) const {
  std::vector<size_t> out;
  const auto& sweeps = Sweeps();
  for (size_t i = 0; i < sweeps.size(); ++i) {
    const int64_t t = sweeps[i].timestamp_us;
    if (t >= lo_us && t <= hi_us) out.push_back(i);
  }
  return out;
}

std::optional<size_t> LidarProvider::Nearest(int64_t t_us) const {
  const auto& sweeps = Sweeps();
  // Sorted by timestamp: the first sweep at or after t, and the one before.
  const auto it = std::lower_bound(
      sweeps.begin(), sweeps.end(), t_us,
      [](const LidarSweepInfo& s, int64_t t) { return s.timestamp_us < t; });
  std::optional<size_t> best;
  int64_t best_gap = INT64_MAX;
  for (auto cand : {it, it == sweeps.begin() ? sweeps.end() : it - 1}) {
    if (cand == sweeps.end()) continue;
    const int64_t gap = std::llabs(cand->timestamp_us - t_us);
    if (gap < best_gap) {
      best_gap = gap;
      best = static_cast<size_t>(cand - sweeps.begin());
    }
  }
  return best;
}

}  // namespace geodrive
