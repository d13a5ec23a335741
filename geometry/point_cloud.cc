#include "geometry/point_cloud.h"

#include <cmath>
#include <cstdint>
#include <cstring>

#include "geometry/util/status.h"

namespace geodrive {

void PointCloud::Reserve(size_t n) { positions.reserve(n); }

void PointCloud::Check(const std::string& what) const {
  CheckAttributes(what);
  // The branch-free scan first, then locate the first bad point for the
  // message.
  if (AllPositionsFinite()) return;
  for (size_t i = 0; i < positions.size(); ++i) {
    GEODRIVE_CHECK_INPUT(positions[i].allFinite(), what, ": point ", i,
                         " is not finite");
  }
}

void PointCloud::CheckAttributes(const std::string& what) const {
  const size_t n = positions.size();
  auto check = [&](size_t m, const char* name) {
    GEODRIVE_CHECK_INPUT(m == 0 || m == n, what, ": attribute '", name, "' has ", m,
                         " entries for ", n, " points");
  };
  check(colors.size(), "colors");
  check(confidence.size(), "confidence");
  check(instance_ids.size(), "instance_ids");
  check(intensity.size(), "intensity");
  check(ring.size(), "ring");
  check(footprints.size(), "footprints");
  check(footprint_u.size(), "footprint_u");
  check(footprint_v.size(), "footprint_v");
  GEODRIVE_CHECK_INPUT(
      footprint_u.size() == footprint_v.size() &&
          (footprint_u.empty() || !footprints.empty()),
      what, ": footprint_u and footprint_v come together, with footprints");
  for (size_t i = 0; i < footprint_u.size(); ++i) {
    GEODRIVE_CHECK_INPUT(
        footprint_u[i].allFinite() && footprint_v[i].allFinite(), what,
        ": point ", i, " has a footprint axis that is not finite");
  }
  // Branch-free scan (finite and >= 0: sign bit clear, exponent not all
  // ones), then the first bad one for the message.
  uint32_t bad_footprint = 0;
  for (float f : footprints) {
    uint32_t u;
    std::memcpy(&u, &f, sizeof u);
    bad_footprint |= (u >> 31) | NotFiniteBit(f);
  }
  for (size_t i = 0; bad_footprint && i < footprints.size(); ++i) {
    GEODRIVE_CHECK_INPUT(std::isfinite(footprints[i]) && footprints[i] >= 0,
                         what, ": point ", i, " has footprint ", footprints[i],
                         " (must be finite and >= 0)");
  }
}

bool PointCloud::AllPositionsFinite() const {
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "packed positions");
  const size_t count = 3 * positions.size();
  const float* values = count ? positions[0].data() : nullptr;
  uint32_t bad = 0;
  for (size_t k = 0; k < count; ++k) bad |= NotFiniteBit(values[k]);
  return bad == 0;
}

Eigen::AlignedBox3f PointCloud::Bounds() const {
  Eigen::AlignedBox3f box;
  for (const auto& p : positions) {
    if (p.allFinite()) box.extend(p);
  }
  return box;
}

namespace {
template <typename T>
void AppendAttr(std::vector<T>& a, const std::vector<T>& b, size_t na, size_t nb) {
  if (nb == 0) return;             // nothing appended: keep a as is
  if (na == 0) {                   // a was empty: take b's attribute
    a = b;
    return;
  }
  if (!a.empty() && !b.empty()) {  // both have it
    a.insert(a.end(), b.begin(), b.end());
  } else {
    a.clear();                     // only one has it: drop
  }
}
template <typename T>
void SelectAttr(const std::vector<T>& in, const std::vector<size_t>& idx, std::vector<T>& out) {
  if (in.empty()) return;
  out.reserve(idx.size());
  for (size_t i : idx) out.push_back(in[i]);
}
}  // namespace

void PointCloud::Append(const PointCloud& other) {
  const size_t na = size(), nb = other.size();
  AppendAttr(colors, other.colors, na, nb);
  AppendAttr(confidence, other.confidence, na, nb);
  AppendAttr(instance_ids, other.instance_ids, na, nb);
  AppendAttr(intensity, other.intensity, na, nb);
  AppendAttr(ring, other.ring, na, nb);
  AppendAttr(footprints, other.footprints, na, nb);
  AppendAttr(footprint_u, other.footprint_u, na, nb);
  AppendAttr(footprint_v, other.footprint_v, na, nb);
  positions.insert(positions.end(), other.positions.begin(), other.positions.end());
}

PointCloud PointCloud::Select(const std::vector<size_t>& indices) const {
  PointCloud out;
  for (size_t i : indices) {
    GEODRIVE_CHECK_INPUT(i < size(), "PointCloud::Select: index ", i, " out of range ", size());
  }
  SelectAttr(positions, indices, out.positions);
  SelectAttr(colors, indices, out.colors);
  SelectAttr(confidence, indices, out.confidence);
  SelectAttr(instance_ids, indices, out.instance_ids);
  SelectAttr(intensity, indices, out.intensity);
  SelectAttr(ring, indices, out.ring);
  SelectAttr(footprints, indices, out.footprints);
  SelectAttr(footprint_u, indices, out.footprint_u);
  SelectAttr(footprint_v, indices, out.footprint_v);
  return out;
}

}  // namespace geodrive
