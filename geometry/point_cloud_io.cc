#include "geometry/point_cloud_io.h"

#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "geometry/util/files.h"
#include "geometry/internal/pcl_adapter.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// Reads a file of `floats_per_point` little-endian float32 values per point.
std::vector<float> ReadFloatRecords(const std::string& path,
                                    size_t floats_per_point,
                                    const char* layout) {
  const std::vector<uint8_t> bytes = ReadFileBytes(path);
  const size_t record = floats_per_point * sizeof(float);
  if (bytes.size() % record != 0) {
    ThrowInputError(path, "size ", bytes.size(), " bytes is not a multiple of ",
                    record, " (", layout, ")");
  }
  std::vector<float> values(bytes.size() / sizeof(float));
  if (!bytes.empty()) std::memcpy(values.data(), bytes.data(), bytes.size());
  for (size_t i = 0; i < values.size(); i += floats_per_point) {
    if (!std::isfinite(values[i]) || !std::isfinite(values[i + 1]) ||
        !std::isfinite(values[i + 2])) {
      ThrowInputError(path, "point ", i / floats_per_point,
                      " has a non-finite coordinate");
    }
  }
  return values;
}

void WriteFloatRecords(const std::string& path,
                       const PointCloud& cloud,
                       bool with_ring) {
  cloud.Check(path);
  const size_t stride = with_ring ? 5 : 4;
  std::vector<float> values(cloud.size() * stride);
  for (size_t i = 0; i < cloud.size(); ++i) {
    float* v = &values[i * stride];
    v[0] = cloud.positions[i].x();
    v[1] = cloud.positions[i].y();
    v[2] = cloud.positions[i].z();
    v[3] = cloud.HasIntensity() ? cloud.intensity[i] : 0.f;
    if (with_ring) v[4] = cloud.HasRing() ? cloud.ring[i] : 0.f;
  }
  WriteFileAtomic(path, values.data(),
                                values.size() * sizeof(float));
}

// Checks that the file can be opened and starts with `magic` (before handing it
// to PCL, which reports problems only on stderr).
void CheckStartsWith(const std::string& path,
                     const std::string& magic,
                     const char* kind) {
  const uint64_t size = FileSizeOrThrow(path);
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) ThrowOpenError(path, errno);
  std::string head(magic.size(), '\0');
  const size_t got = std::fread(&head[0], 1, head.size(), file);
  std::fclose(file);
  if (size == 0)
    ThrowInputError(path, "empty file (expected a ", kind, " file)");
  if (got != head.size() || head != magic)
    ThrowInputError(path, "not a ", kind, " file");
}

// Validates a PCD header (and the size of binary data) before PCL sees the
// file: PCL 1.13's PCDReader crashes on some malformed headers instead of
// returning an error.
void CheckPcdHeader(const std::string& path) {
  const uint64_t file_size = FileSizeOrThrow(path);
  if (file_size == 0) ThrowInputError(path, "empty file (expected a PCD file)");
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) ThrowOpenError(path, errno);
  std::string head(static_cast<size_t>(std::min<uint64_t>(file_size, 1 << 16)),
                   '\0');
  head.resize(std::fread(&head[0], 1, head.size(), file));
  std::fclose(file);

  std::vector<std::string> fields;
  std::vector<int> sizes, counts;
  std::string types, data;
  uint64_t width = 0, height = 0, points = 0;
  bool have_width = false, have_height = false, have_points = false;
  size_t pos = 0, data_start = 0;
  int line_no = 0;
  auto bad = [&](const std::string& what) {
    ThrowInputError(path, "malformed PCD header: ", what, " (line ", line_no,
                    ")");
  };
  auto parse_uint = [&](const std::string& token) -> uint64_t {
    if (token.empty() ||
        token.find_first_not_of("0123456789") != std::string::npos ||
        token.size() > 12) {
      bad("'" + token.substr(0, 20) + "' is not a count");
    }
    return std::stoull(token);
  };
  while (data.empty()) {
    const size_t end = head.find('\n', pos);
    if (end == std::string::npos) {
      ++line_no;
      bad("no DATA line");
    }
    std::string line = head.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    std::string key, token;
    ss >> key;
    std::vector<std::string> values;
    while (ss >> token) values.push_back(token);
    if (key == "VERSION" || key == "VIEWPOINT") {
      continue;
    } else if (key == "FIELDS" || key == "COLUMNS") {
      fields = values;
    } else if (key == "SIZE") {
      for (const auto& v : values) {
        const uint64_t size = parse_uint(v);
        if (size != 1 && size != 2 && size != 4 && size != 8) bad("SIZE " + v);
        sizes.push_back(static_cast<int>(size));
      }
    } else if (key == "TYPE") {
      for (const auto& v : values) {
        if (v != "I" && v != "U" && v != "F") bad("TYPE " + v);
        types += v;
      }
    } else if (key == "COUNT") {
      for (const auto& v : values) {
        const uint64_t count = parse_uint(v);
        if (count == 0 || count > 4096) bad("COUNT " + v);
        counts.push_back(static_cast<int>(count));
      }
    } else if (key == "WIDTH" && values.size() == 1) {
      width = parse_uint(values[0]);
      have_width = true;
    } else if (key == "HEIGHT" && values.size() == 1) {
      height = parse_uint(values[0]);
      have_height = true;
    } else if (key == "POINTS" && values.size() == 1) {
      points = parse_uint(values[0]);
      have_points = true;
    } else if (key == "DATA" && values.empty()) {
      bad("DATA without a format");
    } else if (key == "DATA") {
      data = values[0];
      data_start = pos;
    } else {
      bad("unexpected line '" + line.substr(0, 40) + "'");
    }
  }
  if (fields.empty()) bad("no FIELDS");
  if (counts.empty()) counts.assign(fields.size(), 1);
  if (sizes.size() != fields.size() || types.size() != fields.size() ||
      counts.size() != fields.size()) {
    bad("FIELDS, SIZE, TYPE and COUNT have different lengths");
  }
  if (!have_width || !have_height) bad("missing WIDTH or HEIGHT");
  if (have_points && points != width * height)
    bad("POINTS is not WIDTH x HEIGHT");
  if (data != "ascii" && data != "binary" && data != "binary_compressed") {
    bad("unknown DATA format '" + data.substr(0, 20) + "'");
  }
  uint64_t point_size = 0;
  for (size_t i = 0; i < fields.size(); ++i)
    point_size += uint64_t(sizes[i]) * counts[i];
  const uint64_t available = file_size - data_start;
  if (data == "binary" && width * height * point_size > available) {
    ThrowInputError(path, "truncated: header says ", width * height,
                    " points of ", point_size, " bytes, file has ", available,
                    " bytes of data");
  }
  if (data == "binary_compressed" && width * height > 0 && available < 8) {
    ThrowInputError(path, "truncated: compressed data is missing");
  }
}

// Validates a PLY header and, for ASCII files, that the body holds enough
// numbers: PCL's reader fills missing ASCII points with zeros instead of
// failing. (PCL detects short binary bodies.)
void CheckPly(const std::string& path) {
  CheckStartsWith(path, "ply", "PLY");
  const std::string text = ReadFileText(path);
  size_t pos = 0;
  int line_no = 0;
  bool ascii = false, have_format = false;
  uint64_t min_tokens = 0, element_count = 0;
  uint64_t tokens_per_item = 0;
  auto bad = [&](const std::string& what) {
    ThrowInputError(path, "malformed PLY header: ", what, " (line ", line_no,
                    ")");
  };
  auto flush_element = [&] {
    if (element_count > 0 && tokens_per_item > 0) {
      if (element_count > (uint64_t{1} << 40)) bad("absurd element count");
      min_tokens += element_count * tokens_per_item;
    }
    element_count = 0;
    tokens_per_item = 0;
  };
  while (true) {
    const size_t end = text.find('\n', pos);
    ++line_no;
    if (end == std::string::npos) bad("no end_header");
    std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ss(line);
    std::string key;
    ss >> key;
    if (line_no == 1) continue;  // "ply"
    if (key == "end_header") break;
    if (key == "format") {
      std::string format;
      ss >> format;
      if (format != "ascii" && format != "binary_little_endian" &&
          format != "binary_big_endian") {
        bad("unknown format '" + format.substr(0, 30) + "'");
      }
      ascii = format == "ascii";
      have_format = true;
    } else if (key == "element") {
      flush_element();
      std::string name, count;
      ss >> name >> count;
      if (count.empty() ||
          count.find_first_not_of("0123456789") != std::string::npos ||
          count.size() > 15) {
        bad("bad element count '" + count.substr(0, 20) + "'");
      }
      element_count = std::stoull(count);
    } else if (key == "property") {
      ++tokens_per_item;  // a scalar, or the length of a list
    } else if (key != "comment" && key != "obj_info" && !key.empty()) {
      bad("unexpected line '" + line.substr(0, 40) + "'");
    }
  }
  flush_element();
  if (!have_format) bad("no format line");
  if (!ascii) return;
  uint64_t tokens = 0;
  bool in_token = false;
  for (size_t i = pos; i < text.size(); ++i) {
    const bool space = std::isspace(static_cast<unsigned char>(text[i]));
    if (!space && !in_token) ++tokens;
    in_token = !space;
  }
  if (tokens < min_tokens) {
    ThrowInputError(path, "truncated: header needs at least ", min_tokens,
                    " ASCII values, file has ", tokens);
  }
}

std::string FormatFloat(float v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.9g",
                static_cast<double>(v));  // round-trips float32
  return buf;
}

}  // namespace

PointCloud ReadNuscenesLidarBin(const std::string& path) {
  const std::vector<float> v =
      ReadFloatRecords(path, 5, "float32 x 5 per point: x y z intensity ring");
  PointCloud cloud;
  const size_t n = v.size() / 5;
  cloud.Reserve(n);
  cloud.intensity.reserve(n);
  cloud.ring.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    cloud.positions.emplace_back(v[5 * i], v[5 * i + 1], v[5 * i + 2]);
    cloud.intensity.push_back(v[5 * i + 3]);
    cloud.ring.push_back(v[5 * i + 4]);
  }
  return cloud;
}

void WriteNuscenesLidarBin(const std::string& path, const PointCloud& cloud) {
  WriteFloatRecords(path, cloud, /*with_ring=*/true);
}

PointCloud ReadKittiVelodyneBin(const std::string& path) {
  const std::vector<float> v =
      ReadFloatRecords(path, 4, "float32 x 4 per point: x y z reflectance");
  PointCloud cloud;
  const size_t n = v.size() / 4;
  cloud.Reserve(n);
  cloud.intensity.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    cloud.positions.emplace_back(v[4 * i], v[4 * i + 1], v[4 * i + 2]);
    cloud.intensity.push_back(v[4 * i + 3]);
  }
  return cloud;
}

void WriteKittiVelodyneBin(const std::string& path, const PointCloud& cloud) {
  WriteFloatRecords(path, cloud, /*with_ring=*/false);
}

PointCloud ReadPly(const std::string& path) {
  CheckPly(path);
  pcl::PCLPointCloud2 cloud2;
  int status = -1;
  {
    internal::PclQuietGuard quiet;
    try {
      pcl::PLYReader reader;
      Eigen::Vector4f origin;
      Eigen::Quaternionf orientation;
      int ply_version = 0;
      status = reader.read(path, cloud2, origin, orientation, ply_version, 0);
    } catch (const std::exception& e) {
      ThrowInputError(path, "malformed PLY file (", e.what(), ")");
    }
  }
  if (status < 0)
    ThrowInputError(path,
                    "malformed or truncated PLY file (PCL could not parse it)");
  return internal::FromPclPointCloud2(cloud2, path);
}

void WritePly(const std::string& path, const PointCloud& cloud, bool binary) {
  cloud.Check(path);
  std::string out = "ply\n";
  out += binary ? "format binary_little_endian 1.0\n" : "format ascii 1.0\n";
  out += "comment written by geodrive\n";
  out += "element vertex " + std::to_string(cloud.size()) + "\n";
  out += "property float x\nproperty float y\nproperty float z\n";
  if (cloud.HasColors())
    out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (cloud.HasConfidence()) out += "property float confidence\n";
  if (cloud.HasInstanceIds()) out += "property int instance_id\n";
  if (cloud.HasIntensity()) out += "property float intensity\n";
  if (cloud.HasRing()) out += "property float ring\n";
  out += "end_header\n";
  auto put = [&out](const void* p, size_t n) {
    out.append(static_cast<const char*>(p), n);
  };
  for (size_t i = 0; i < cloud.size(); ++i) {
    if (binary) {
      put(cloud.positions[i].data(), 12);
      if (cloud.HasColors()) put(cloud.colors[i].data(), 3);
      if (cloud.HasConfidence()) put(&cloud.confidence[i], 4);
      if (cloud.HasInstanceIds()) put(&cloud.instance_ids[i], 4);
      if (cloud.HasIntensity()) put(&cloud.intensity[i], 4);
      if (cloud.HasRing()) put(&cloud.ring[i], 4);
    } else {
      std::string line = FormatFloat(cloud.positions[i].x()) + " " +
                         FormatFloat(cloud.positions[i].y()) + " " +
                         FormatFloat(cloud.positions[i].z());
      if (cloud.HasColors()) {
        for (int k = 0; k < 3; ++k)
          line += " " + std::to_string(int{cloud.colors[i][k]});
      }
      if (cloud.HasConfidence()) line += " " + FormatFloat(cloud.confidence[i]);
      if (cloud.HasInstanceIds())
        line += " " + std::to_string(cloud.instance_ids[i]);
      if (cloud.HasIntensity()) line += " " + FormatFloat(cloud.intensity[i]);
      if (cloud.HasRing()) line += " " + FormatFloat(cloud.ring[i]);
      out += line + "\n";
    }
  }
  WriteFileAtomic(path, out);
}

PointCloud ReadPcd(const std::string& path) {
  CheckPcdHeader(path);
  pcl::PCLPointCloud2 cloud2;
  int status = -1;
  {
    internal::PclQuietGuard quiet;
    try {
      pcl::PCDReader reader;
      status = reader.read(path, cloud2);
    } catch (const std::exception& e) {
      ThrowInputError(path, "malformed PCD file (", e.what(), ")");
    }
  }
  if (status < 0)
    ThrowInputError(path,
                    "malformed or truncated PCD file (PCL could not parse it)");
  return internal::FromPclPointCloud2(cloud2, path);
}

void WritePcd(const std::string& path, const PointCloud& cloud, bool binary) {
  cloud.Check(path);
  const pcl::PCLPointCloud2 cloud2 = internal::ToPclPointCloud2(cloud);
  WriteViaTemporary(path, ".pcd", [&](const std::string& tmp) {
    internal::PclQuietGuard quiet;
    pcl::PCDWriter writer;
    if (cloud.empty()) {
      // PCL refuses to write clouds without data; an empty PCD is just the
      // header.
      std::string header = writer.generateHeaderASCII(
          cloud2, Eigen::Vector4f::Zero(), Eigen::Quaternionf::Identity());
      header += "DATA ascii\n";
      WriteFileAtomic(tmp, header);
      return true;
    }
    if (!binary) {
      return writer.writeASCII(tmp, cloud2, Eigen::Vector4f::Zero(),
                               Eigen::Quaternionf::Identity(), 9) == 0;
    }
    if (writer.writeBinary(tmp, cloud2) != 0) return false;
    // PCL 1.13 over-allocates binary files by up to a page of trailing zeros;
    // trim them.
    const std::string header =
        writer.generateHeaderBinary(cloud2, Eigen::Vector4f::Zero(),
                                    Eigen::Quaternionf::Identity()) +
        "DATA binary\n";
    std::error_code ec;
    const uint64_t want = header.size() + cloud2.data.size();
    if (std::filesystem::file_size(tmp, ec) > want && !ec) {
      std::filesystem::resize_file(tmp, want, ec);
    }
    return !ec;
  });
}

PointCloud ReadPointCloud(const std::string& path) {
  const std::string name = LowerFileName(path);
  if (EndsWith(name, ".ply")) return ReadPly(path);
  if (EndsWith(name, ".pcd")) return ReadPcd(path);
  if (EndsWith(name, ".pcd.bin")) return ReadNuscenesLidarBin(path);
  if (EndsWith(name, ".bin")) return ReadKittiVelodyneBin(path);
  ThrowInputError(
      path,
      "unknown point cloud format (expected .ply, .pcd, .pcd.bin or .bin)");
}

void WritePointCloud(const std::string& path, const PointCloud& cloud) {
  const std::string name = LowerFileName(path);
  if (EndsWith(name, ".ply")) return WritePly(path, cloud);
  if (EndsWith(name, ".pcd")) return WritePcd(path, cloud);
  if (EndsWith(name, ".pcd.bin"))
    return WriteNuscenesLidarBin(path, cloud);
  if (EndsWith(name, ".bin"))
    return WriteKittiVelodyneBin(path, cloud);
  ThrowInputError(
      path,
      "unknown point cloud format (expected .ply, .pcd, .pcd.bin or .bin)");
}

}  // namespace geodrive
