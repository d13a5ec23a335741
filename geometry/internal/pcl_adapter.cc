#include "geometry/internal/pcl_adapter.h"

#include <pcl/console/print.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "geometry/util/status.h"

namespace geodrive {
namespace internal {
namespace {

uint32_t PackRgb(const Color3u8& c) {
  return (uint32_t{c[0]} << 16) | (uint32_t{c[1]} << 8) | uint32_t{c[2]};
}
Color3u8 UnpackRgb(uint32_t v) {
  return Color3u8(static_cast<uint8_t>((v >> 16) & 0xff),
                  static_cast<uint8_t>((v >> 8) & 0xff),
                  static_cast<uint8_t>(v & 0xff));
}

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

size_t FieldTypeSize(uint8_t datatype) {
  switch (datatype) {
    case pcl::PCLPointField::INT8:
    case pcl::PCLPointField::UINT8:
      return 1;
    case pcl::PCLPointField::INT16:
    case pcl::PCLPointField::UINT16:
      return 2;
    case pcl::PCLPointField::INT32:
    case pcl::PCLPointField::UINT32:
    case pcl::PCLPointField::FLOAT32:
      return 4;
    case pcl::PCLPointField::FLOAT64:
      return 8;
    default:
      return 0;
  }
}

template <typename T>
T Load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

double LoadAsDouble(const uint8_t* p, uint8_t datatype) {
  switch (datatype) {
    case pcl::PCLPointField::INT8:
      return Load<int8_t>(p);
    case pcl::PCLPointField::UINT8:
      return Load<uint8_t>(p);
    case pcl::PCLPointField::INT16:
      return Load<int16_t>(p);
    case pcl::PCLPointField::UINT16:
      return Load<uint16_t>(p);
    case pcl::PCLPointField::INT32:
      return Load<int32_t>(p);
    case pcl::PCLPointField::UINT32:
      return Load<uint32_t>(p);
    case pcl::PCLPointField::FLOAT32:
      return Load<float>(p);
    case pcl::PCLPointField::FLOAT64:
      return Load<double>(p);
    default:
      return std::numeric_limits<double>::quiet_NaN();
  }
}

uint32_t LoadBits32(const uint8_t* p) { return Load<uint32_t>(p); }

void AddField(pcl::PCLPointCloud2* cloud,
              const std::string& name,
              uint8_t datatype) {
  pcl::PCLPointField field;
  field.name = name;
  field.offset = cloud->point_step;
  field.datatype = datatype;
  field.count = 1;
  cloud->fields.push_back(field);
  cloud->point_step += static_cast<uint32_t>(FieldTypeSize(datatype));
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

pcl::PCLPointCloud2 ToPclPointCloud2(const PointCloud& cloud) {
  pcl::PCLPointCloud2 out;
  out.point_step = 0;
  AddField(&out, "x", pcl::PCLPointField::FLOAT32);
  AddField(&out, "y", pcl::PCLPointField::FLOAT32);
  AddField(&out, "z", pcl::PCLPointField::FLOAT32);
  if (cloud.HasColors()) AddField(&out, "rgb", pcl::PCLPointField::FLOAT32);
  if (cloud.HasIntensity())
    AddField(&out, "intensity", pcl::PCLPointField::FLOAT32);
  if (cloud.HasConfidence())
    AddField(&out, "confidence", pcl::PCLPointField::FLOAT32);
  if (cloud.HasInstanceIds())
    AddField(&out, "instance_id", pcl::PCLPointField::INT32);
  if (cloud.HasRing()) AddField(&out, "ring", pcl::PCLPointField::FLOAT32);
  out.width = static_cast<uint32_t>(cloud.size());
  out.height = 1;
  out.is_bigendian = false;
  out.row_step = out.point_step * out.width;
  out.is_dense = true;
  out.data.resize(static_cast<size_t>(out.row_step));
  for (size_t i = 0; i < cloud.size(); ++i) {
    uint8_t* p = out.data.data() + i * out.point_step;
    size_t f = 0;
    for (int k = 0; k < 3; ++k) {
      const float v = cloud.positions[i][k];
      if (!std::isfinite(v)) out.is_dense = false;
      std::memcpy(p + out.fields[f++].offset, &v, 4);
    }
    if (cloud.HasColors()) {
      const uint32_t rgb = PackRgb(cloud.colors[i]);
      std::memcpy(p + out.fields[f++].offset, &rgb, 4);
    }
    if (cloud.HasIntensity())
      std::memcpy(p + out.fields[f++].offset, &cloud.intensity[i], 4);
    if (cloud.HasConfidence())
      std::memcpy(p + out.fields[f++].offset, &cloud.confidence[i], 4);
    if (cloud.HasInstanceIds()) {
      std::memcpy(p + out.fields[f++].offset, &cloud.instance_ids[i], 4);
    }
    if (cloud.HasRing())
      std::memcpy(p + out.fields[f++].offset, &cloud.ring[i], 4);
  }
  return out;
}

PointCloud FromPclPointCloud2(const pcl::PCLPointCloud2& cloud,
                              const std::string& what) {
  auto find = [&](const std::string& name) -> const pcl::PCLPointField* {
    for (const auto& field : cloud.fields) {
      if (field.name == name) {
        const size_t size = FieldTypeSize(field.datatype);
        if (size == 0 || field.offset + size > cloud.point_step) {
          ThrowInputError(what, "field '", name,
                          "' has an unsupported type or layout");
        }
        return &field;
      }
    }
    return nullptr;
  };
  const pcl::PCLPointField* fx = find("x");
  const pcl::PCLPointField* fy = find("y");
  const pcl::PCLPointField* fz = find("z");
  if (!fx || !fy || !fz) ThrowInputError(what, "no x/y/z fields");
  if (cloud.is_bigendian)
    ThrowInputError(what, "big-endian point data is not supported");
  const pcl::PCLPointField* frgb = find("rgb");
  if (!frgb) frgb = find("rgba");
  if (frgb && FieldTypeSize(frgb->datatype) != 4) frgb = nullptr;
  const pcl::PCLPointField* fred = find("red");
  const pcl::PCLPointField* fgreen = find("green");
  const pcl::PCLPointField* fblue = find("blue");
  const bool separate_rgb = !frgb && fred && fgreen && fblue;
  const pcl::PCLPointField* fintensity = find("intensity");
  const pcl::PCLPointField* fconfidence = find("confidence");
  const pcl::PCLPointField* finstance = find("instance_id");
  const pcl::PCLPointField* fring = find("ring");

  const uint64_t n = uint64_t{cloud.width} * cloud.height;
  if (cloud.point_step == 0 ||
      uint64_t{cloud.row_step} * cloud.height > cloud.data.size() ||
      n * cloud.point_step > cloud.data.size() ||
      uint64_t{cloud.row_step} < uint64_t{cloud.point_step} * cloud.width) {
    ThrowInputError(what, "point data (", cloud.data.size(),
                    " bytes) is inconsistent with ", cloud.width, "x",
                    cloud.height, " points of ", cloud.point_step, " bytes");
  }
  PointCloud out;
  out.Reserve(n);
  for (uint32_t row = 0; row < cloud.height; ++row) {
    for (uint32_t col = 0; col < cloud.width; ++col) {
      const uint8_t* p = cloud.data.data() + uint64_t{row} * cloud.row_step +
                         uint64_t{col} * cloud.point_step;
      const float x =
          static_cast<float>(LoadAsDouble(p + fx->offset, fx->datatype));
      const float y =
          static_cast<float>(LoadAsDouble(p + fy->offset, fy->datatype));
      const float z =
          static_cast<float>(LoadAsDouble(p + fz->offset, fz->datatype));
      if (!Finite(x, y, z)) continue;
      out.positions.emplace_back(x, y, z);
      if (frgb) {
        out.colors.push_back(UnpackRgb(LoadBits32(p + frgb->offset)));
      } else if (separate_rgb) {
        auto channel = [&](const pcl::PCLPointField* f) {
          const double v = LoadAsDouble(p + f->offset, f->datatype);
          return static_cast<uint8_t>(std::clamp(std::lround(v), 0l, 255l));
        };
        out.colors.emplace_back(channel(fred), channel(fgreen), channel(fblue));
      }
      if (fintensity) {
        out.intensity.push_back(static_cast<float>(
            LoadAsDouble(p + fintensity->offset, fintensity->datatype)));
      }
      if (fconfidence) {
        out.confidence.push_back(static_cast<float>(
            LoadAsDouble(p + fconfidence->offset, fconfidence->datatype)));
      }
      if (finstance) {
        out.instance_ids.push_back(static_cast<int32_t>(
            LoadAsDouble(p + finstance->offset, finstance->datatype)));
      }
      if (fring) {
        out.ring.push_back(static_cast<float>(
            LoadAsDouble(p + fring->offset, fring->datatype)));
      }
    }
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
