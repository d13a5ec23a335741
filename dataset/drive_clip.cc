#include "dataset/drive_clip.h"

#include <algorithm>
#include <cstdlib>

namespace geodrive {

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
