#include "geometry/trajectory_io.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string_view>

#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// Formats a double as Python's repr()/str() does (shortest round-trip digits;
// fixed notation when the decimal exponent is in [-4, 16), else "1e-05" style),
// so files match MonST3R's writer.
std::string PythonFloatRepr(double x) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x < 0 ? "-inf" : "inf";
  if (x == 0) return std::signbit(x) ? "-0.0" : "0.0";
  char buf[64];
  const auto res =
      std::to_chars(buf, buf + sizeof(buf), x, std::chars_format::scientific);
  const std::string sci(buf, res.ptr);  // e.g. "-1.2345e-05"
  size_t pos = 0;
  std::string sign;
  if (sci[0] == '-') {
    sign = "-";
    pos = 1;
  }
  const size_t e = sci.find('e');
  std::string digits;
  for (size_t i = pos; i < e; ++i) {
    if (sci[i] != '.') digits += sci[i];
  }
  const int exponent = std::stoi(sci.substr(e + 1));
  const int decpt = exponent + 1;  // value = 0.DIGITS * 10^decpt
  const int ndigits = static_cast<int>(digits.size());
  if (decpt > -4 && decpt <= 16) {
    if (decpt <= 0) return sign + "0." + std::string(-decpt, '0') + digits;
    if (decpt >= ndigits)
      return sign + digits + std::string(decpt - ndigits, '0') + ".0";
    return sign + digits.substr(0, decpt) + "." + digits.substr(decpt);
  }
  std::string out = sign + digits.substr(0, 1);
  if (ndigits > 1) out += "." + digits.substr(1);
  const int abs_exp = std::abs(exponent);
  out += exponent < 0 ? "e-" : "e+";
  if (abs_exp < 10) out += "0";
  return out + std::to_string(abs_exp);
}

std::string FormatFixed6(double x) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.6f", x);
  return buf;
}

// Splits the file into numeric rows. Blank lines and lines starting with '#'
// are skipped. Every row must have `columns` finite numbers; errors name the
// file and the 1-based line.
struct Row {
  int line = 0;
  std::vector<double> values;
};

std::vector<Row> ReadRows(const std::string& path,
                          size_t columns,
                          const char* layout) {
  const std::string text = ReadFileText(path);
  std::vector<Row> rows;
  size_t start = 0;
  int line_no = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + start, end - start);
    start = end + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    size_t first = line.find_first_not_of(" \t");
    if (first == std::string_view::npos || line[first] == '#') continue;
    Row row;
    row.line = line_no;
    size_t p = first;
    while (p < line.size()) {
      size_t q = line.find_first_of(" \t,", p);
      if (q == std::string_view::npos) q = line.size();
      const std::string_view token = line.substr(p, q - p);
      if (!token.empty()) {
        double v = 0;
        const char* begin = token.data();
        if (token[0] == '+') ++begin;
        const auto r = std::from_chars(begin, token.data() + token.size(), v);
        if (r.ec != std::errc() || r.ptr != token.data() + token.size()) {
          ThrowInputError(path, "line ", line_no, ": not a number: '",
                          std::string(token.substr(0, 40)), "'");
        }
        if (!std::isfinite(v)) {
          ThrowInputError(path, "line ", line_no, ": non-finite value '",
                          std::string(token), "'");
        }
        row.values.push_back(v);
      }
      p = line.find_first_not_of(" \t,", q);
      if (p == std::string_view::npos) break;
    }
    if (row.values.size() != columns) {
      ThrowInputError(path, "line ", line_no, ": expected ", columns,
                      " numbers (", layout, "), found ", row.values.size());
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

Eigen::Quaterniond NormalizedQuaternion(const std::string& path,
                                        int line,
                                        const Eigen::Quaterniond& q) {
  const double norm = q.norm();
  if (!(norm > 1e-8)) ThrowInputError(path, "line ", line, ": zero quaternion");
  return Eigen::Quaterniond(q.coeffs() / norm);
}

enum class QuatOrder { kWxyz, kXyzw };

Trajectory ReadTrajectory(const std::string& path, QuatOrder order) {
  const char* layout =
      order == QuatOrder::kWxyz ? "t x y z qw qx qy qz" : "t x y z qx qy qz qw";
  Trajectory trajectory;
  for (const Row& row : ReadRows(path, 8, layout)) {
    const auto& v = row.values;
    const Eigen::Quaterniond q =
        order == QuatOrder::kWxyz ? QuaternionFromWxyz(v[4], v[5], v[6], v[7])
                                  : QuaternionFromXyzw(v[4], v[5], v[6], v[7]);
    if (!trajectory.empty() && !(v[0] > trajectory.timestamps.back())) {
      ThrowInputError(path, "line ", row.line, ": timestamp ",
                      PythonFloatRepr(v[0]),
                      " is not greater than the previous one (",
                      PythonFloatRepr(trajectory.timestamps.back()), ")");
    }
    trajectory.Add(v[0], Rigid3d(NormalizedQuaternion(path, row.line, q),
                                 Eigen::Vector3d(v[1], v[2], v[3])));
  }
  return trajectory;
}

void WriteTrajectory(const std::string& path,
                     const Trajectory& trajectory,
                     QuatOrder order) {
  trajectory.Check(path);
  std::string text;
  for (size_t i = 0; i < trajectory.size(); ++i) {
    const Rigid3d& pose = trajectory.world_from_cam[i];
    const Eigen::Vector4d q = order == QuatOrder::kWxyz
                                  ? QuaternionToWxyz(pose.rotation)
                                  : QuaternionToXyzw(pose.rotation);
    text += PythonFloatRepr(trajectory.timestamps[i]);
    for (int k = 0; k < 3; ++k)
      text += " " + PythonFloatRepr(pose.translation[k]);
    for (int k = 0; k < 4; ++k) text += " " + PythonFloatRepr(q[k]);
    text += "\n";
  }
  WriteFileAtomic(path, text);
}

}  // namespace

Trajectory ReadMonst3rTrajectory(const std::string& path) {
  return ReadTrajectory(path, QuatOrder::kWxyz);
}

void WriteMonst3rTrajectory(const std::string& path,
                            const Trajectory& trajectory) {
  WriteTrajectory(path, trajectory, QuatOrder::kWxyz);
}

Trajectory ReadTumTrajectory(const std::string& path) {
  return ReadTrajectory(path, QuatOrder::kXyzw);
}

void WriteTumTrajectory(const std::string& path, const Trajectory& trajectory) {
  WriteTrajectory(path, trajectory, QuatOrder::kXyzw);
}

Trajectory ReadKittiTrajectory(const std::string& path,
                               const std::string& times_path) {
  const std::vector<Row> rows = ReadRows(
      path, 12, "12 numbers: the row-major 3x4 world_from_cam0 (KITTI poses)");
  std::vector<double> times;
  if (!times_path.empty()) {
    for (const Row& r : ReadRows(times_path, 1, "one timestamp (seconds)"))
      times.push_back(r.values[0]);
    GEODRIVE_CHECK_INPUT(times.size() == rows.size(), times_path, ": ",
                         times.size(), " timestamps for ", rows.size(),
                         " poses in ", path);
  }
  Trajectory t;
  for (size_t i = 0; i < rows.size(); ++i) {
    Matrix3x4d m;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = rows[i].values[r * 4 + c];
    Rigid3d pose;
    try {
      pose = Rigid3d::FromMatrix3x4(m, 1e-5);
    } catch (const InputError& e) {
      ThrowInputError(path, "line ", rows[i].line, ": ", e.what());
    }
    pose.rotation.normalize();
    const double stamp = times.empty() ? static_cast<double>(i) : times[i];
    GEODRIVE_CHECK_INPUT(t.empty() || stamp > t.timestamps.back(),
                         times_path.empty() ? path : times_path, " line ",
                         i + 1, ": timestamps must increase");
    t.Add(stamp, pose);
  }
  GEODRIVE_CHECK_INPUT(!t.empty(), path, ": no poses");
  return t;
}

Trajectory ReadColmapTrajectory(const std::string& path) {
  const std::string text = ReadFileText(path);
  std::vector<std::pair<std::string, Rigid3d>> images;
  size_t start = 0;
  int line_no = 0;
  long declared_images = -1;  // from the header comment, when present
  bool expect_points = false;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(start, end - start);
    start = end + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const size_t first = line.find_first_not_of(" \t");
    if (first != std::string::npos && line[first] == '#') {
      // COLMAP's header states the count: "# Number of images: N, ...".
      const std::string key = "Number of images:";
      const size_t at = line.find(key);
      if (at != std::string::npos)
        declared_images =
            std::strtol(line.c_str() + at + key.size(), nullptr, 10);
      continue;
    }
    if (expect_points) {  // the image's 2D points (may be empty)
      expect_points = false;
      // Triples "X Y POINT3D_ID": all numbers. A line ending in a name is
      // the next image: the file lost its points lines, and skipping it
      // would drop every second image.
      std::istringstream ps(line);
      std::string token, last;
      while (ps >> token) last = token;
      char* rest = nullptr;
      if (!last.empty()) std::strtod(last.c_str(), &rest);
      GEODRIVE_CHECK_INPUT(
          last.empty() || (rest && *rest == '\0'), path, " line ", line_no,
          ": expected the 2D points line of image '", images.back().first,
          "' (empty if it has none), found another image "
          "line: every image line must be followed by its "
          "points line");
      continue;
    }
    if (first == std::string::npos) continue;
    std::istringstream ls(line);
    long id = 0, camera_id = 0;
    double qw, qx, qy, qz, tx, ty, tz;
    std::string name;
    if (!(ls >> id >> qw >> qx >> qy >> qz >> tx >> ty >> tz >> camera_id >>
          name)) {
      ThrowInputError(
          path, "line ", line_no,
          ": expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME");
    }
    const Eigen::Quaterniond q(qw, qx, qy, qz);
    const Eigen::Vector3d tr(tx, ty, tz);
    GEODRIVE_CHECK_INPUT(q.coeffs().allFinite() && tr.allFinite(), path,
                         " line ", line_no, ": non-finite pose");
    GEODRIVE_CHECK_INPUT(std::abs(q.norm() - 1) < 1e-3, path, " line ", line_no,
                         ": quaternion norm ", q.norm(),
                         " (expected unit QW QX QY QZ)");
    const Rigid3d cam_from_world(q.normalized(), tr);
    images.emplace_back(name, cam_from_world.Inverse());
    expect_points = true;
  }
  GEODRIVE_CHECK_INPUT(!images.empty(), path, ": no images");
  GEODRIVE_CHECK_INPUT(declared_images < 0 ||
                           declared_images == static_cast<long>(images.size()),
                       path, ": the header says ", declared_images,
                       " images, the file holds ", images.size());
  std::stable_sort(
      images.begin(), images.end(),
      [](const auto& a, const auto& b) { return a.first < b.first; });
  Trajectory t;
  for (size_t i = 0; i < images.size(); ++i) {
    GEODRIVE_CHECK_INPUT(i == 0 || images[i].first != images[i - 1].first, path,
                         ": image name '", images[i].first, "' appears twice");
    t.Add(static_cast<double>(i), images[i].second);
  }
  return t;
}

std::vector<PinholeCamera> ReadMonst3rIntrinsics(const std::string& path,
                                                 int width,
                                                 int height) {
  std::vector<PinholeCamera> cameras;
  for (const Row& row :
       ReadRows(path, 9, "row-major 3x3 K: fx 0 cx 0 fy cy 0 0 1")) {
    const auto& v = row.values;
    if (v[1] != 0 || v[3] != 0 || v[6] != 0 || v[7] != 0 || v[8] != 1) {
      ThrowInputError(
          path, "line ", row.line,
          ": not a pinhole K (expected fx 0 cx 0 fy cy 0 0 1 with zero skew)");
    }
    if (!(v[0] > 0) || !(v[4] > 0)) {
      ThrowInputError(path, "line ", row.line,
                      ": focal lengths must be positive (fx ", v[0], ", fy ",
                      v[4], ")");
    }
    cameras.emplace_back(v[0], v[4], v[2], v[5], width, height);
  }
  return cameras;
}

void WriteMonst3rIntrinsics(const std::string& path,
                            const std::vector<PinholeCamera>& cameras) {
  std::string text;
  for (const PinholeCamera& camera : cameras) {
    const Eigen::Matrix3d K = camera.K();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c)
        text += (r || c ? " " : "") + FormatFixed6(K(r, c));
    }
    text += "\n";
  }
  WriteFileAtomic(path, text);
}

}  // namespace geodrive
