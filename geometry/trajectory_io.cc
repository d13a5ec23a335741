#include "geometry/trajectory_io.h"

#include <charconv>
#include <cmath>
#include <cstdio>
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
