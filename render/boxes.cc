#include "render/boxes.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>

#include "geometry/util/files.h"
#include "geometry/util/json_fields.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

using json = nlohmann::json;
using internal::JsonNumber;
using internal::JsonVector;

constexpr int kMaxImageSide = 16384;
constexpr int kMaxFrames = 1000000;

int Integer(const std::string& path,
            const json& j,
            const std::string& where,
            int lo,
            int hi) {
  if (!j.is_number_integer())
    ThrowInputError(path, where, " must be an integer");
  const int64_t v = j.get<int64_t>();
  if (v < lo || v > hi)
    ThrowInputError(path, where, " = ", v, " is outside ", lo, "..", hi);
  return static_cast<int>(v);
}

std::string String(const std::string& path,
                   const json& j,
                   const std::string& where) {
  if (!j.is_string()) ThrowInputError(path, where, " must be a string");
  return j.get<std::string>();
}

void CheckKeys(const std::string& path,
               const json& j,
               const std::string& where,
               const std::set<std::string>& allowed) {
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (!allowed.count(it.key()))
      ThrowInputError(path, where, ": unknown key \"", it.key(), "\"");
  }
}

json VectorJson(const Eigen::VectorXd& v) {
  json out = json::array();
  for (int i = 0; i < v.size(); ++i) out.push_back(v[i]);
  return out;
}

}  // namespace

double Box2d::Area() const {
  if (!IsFinite() || xmax <= xmin || ymax <= ymin) return 0.0;
  return (xmax - xmin) * (ymax - ymin);
}

bool Box2d::IsFinite() const {
  return std::isfinite(xmin) && std::isfinite(ymin) && std::isfinite(xmax) &&
         std::isfinite(ymax);
}

bool Box2d::IsOrdered() const { return xmin <= xmax && ymin <= ymax; }

Box2d Box2d::Scaled(double sx, double sy) const {
  return Box2d{xmin * sx, ymin * sy, xmax * sx, ymax * sy};
}

Box2d Box2d::Clipped(int width, int height) const {
  Box2d b{std::clamp(xmin, 0.0, double(width)),
          std::clamp(ymin, 0.0, double(height)),
          std::clamp(xmax, 0.0, double(width)),
          std::clamp(ymax, 0.0, double(height))};
  return b;
}

Box2d Interpolate(const Box2d& a, const Box2d& b, double t) {
  return Box2d{(1 - t) * a.xmin + t * b.xmin, (1 - t) * a.ymin + t * b.ymin,
               (1 - t) * a.xmax + t * b.xmax, (1 - t) * a.ymax + t * b.ymax};
}

std::optional<Box2d> ProjectBox3d(const Box3d& box,
                                  const PinholeCamera& camera,
                                  const Rigid3d& cam_from_world,
                                  double near) {
  Box2d out{std::numeric_limits<double>::infinity(),
            std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity()};
  bool any = false;
  for (const Eigen::Vector3d& corner : box.Corners()) {
    const Eigen::Vector3d p = cam_from_world * corner;
    if (!(p.z() > near)) continue;
    const Eigen::Vector2d uv = camera.Project(p);
    out.xmin = std::min(out.xmin, uv.x());
    out.ymin = std::min(out.ymin, uv.y());
    out.xmax = std::max(out.xmax, uv.x());
    out.ymax = std::max(out.ymax, uv.y());
    any = true;
  }
  if (!any) return std::nullopt;
  return out;
}

const BoxFrame* BoxSequence::Find(int frame) const {
  auto it =
      std::lower_bound(frames.begin(), frames.end(), frame,
                       [](const BoxFrame& f, int v) { return f.frame < v; });
  return (it != frames.end() && it->frame == frame) ? &*it : nullptr;
}

bool BoxSequence::HasAll3d() const {
  for (const BoxFrame& f : frames)
    if (!f.box_3d) return false;
  return !frames.empty();
}

const BoxSequence* BoxSequences::Find(const std::string& id) const {
  for (const BoxSequence& s : instances)
    if (s.id == id) return &s;
  return nullptr;
}

void BoxSequences::Check(const std::string& what) const {
  GEODRIVE_CHECK_INPUT(image_width >= 1 && image_width <= kMaxImageSide &&
                           image_height >= 1 && image_height <= kMaxImageSide,
                       what, ": image size ", image_width, "x", image_height,
                       " (W x H) must be in 1..", kMaxImageSide);
  GEODRIVE_CHECK_INPUT(num_frames >= 1 && num_frames <= kMaxFrames, what,
                       ": num_frames ", num_frames, " must be in 1..",
                       kMaxFrames);
  std::set<std::string> ids;
  for (size_t i = 0; i < instances.size(); ++i) {
    const BoxSequence& s = instances[i];
    const std::string where =
        what + ": instance " + std::to_string(i) + " ('" + s.id + "')";
    GEODRIVE_CHECK_INPUT(!s.id.empty(), what, ": instance ", i,
                         " has an empty id");
    GEODRIVE_CHECK_INPUT(ids.insert(s.id).second, where,
                         ": duplicate instance id");
    int previous = -1;
    for (const BoxFrame& f : s.frames) {
      const std::string fw = where + " frame " + std::to_string(f.frame);
      GEODRIVE_CHECK_INPUT(f.frame >= 0 && f.frame < num_frames, fw,
                           ": frame index outside 0..", num_frames - 1);
      GEODRIVE_CHECK_INPUT(
          f.frame > previous, fw,
          ": frames must be listed once each in increasing order");
      previous = f.frame;
      GEODRIVE_CHECK_INPUT(f.box_2d || f.box_3d, fw,
                           ": needs box_2d or box_3d");
      if (f.box_2d) {
        const Box2d& b = *f.box_2d;
        GEODRIVE_CHECK_INPUT(b.IsFinite(), fw,
                             ": box_2d has NaN or Inf values");
        GEODRIVE_CHECK_INPUT(b.IsOrdered(), fw, ": box_2d [", b.xmin, ", ",
                             b.ymin, ", ", b.xmax, ", ", b.ymax,
                             "] is inverted (need xmin <= xmax, ymin <= ymax)");
      }
      if (f.box_3d) {
        GEODRIVE_CHECK_INPUT(
            f.box_3d->IsValid(), fw,
            ": box_3d must be finite with size > 0 and a unit quaternion");
      }
      if (f.visibility) {
        GEODRIVE_CHECK_INPUT(*f.visibility >= 0 && *f.visibility <= 1, fw,
                             ": visibility ", *f.visibility,
                             " must be in [0, 1]");
      }
    }
  }
}

BoxSequences ReadBoxesJson(const std::string& path) {
  const json root = internal::ReadJsonObjectFile(path);
  CheckKeys(path, root, "top level",
            {"format", "version", "image_width", "image_height", "num_frames",
             "units", "instances", "description"});
  if (internal::JsonString(path, root, "format", "") != "geodrive-boxes")
    ThrowInputError(path, "\"format\" must be \"geodrive-boxes\"");
  if (!root.contains("version") || !root["version"].is_number_integer() ||
      root["version"] != 1)
    ThrowInputError(path, "unsupported \"version\" (expected 1)");
  BoxSequences boxes;
  for (const char* key :
       {"image_width", "image_height", "num_frames", "instances"}) {
    if (!root.contains(key)) ThrowInputError(path, "missing \"", key, "\"");
  }
  boxes.image_width =
      Integer(path, root["image_width"], "image_width", 1, kMaxImageSide);
  boxes.image_height =
      Integer(path, root["image_height"], "image_height", 1, kMaxImageSide);
  boxes.num_frames =
      Integer(path, root["num_frames"], "num_frames", 1, kMaxFrames);
  if (root.contains("units"))
    boxes.units = String(path, root["units"], "units");
  const json& instances = root["instances"];
  if (!instances.is_array())
    ThrowInputError(path, "\"instances\" must be an array");
  for (size_t i = 0; i < instances.size(); ++i) {
    const json& ji = instances[i];
    const std::string where = "instances[" + std::to_string(i) + "]";
    if (!ji.is_object()) ThrowInputError(path, where, " must be an object");
    CheckKeys(path, ji, where, {"id", "category", "frames"});
    if (!ji.contains("id") || !ji.contains("frames"))
      ThrowInputError(path, where, " needs \"id\" and \"frames\"");
    BoxSequence seq;
    seq.id = String(path, ji["id"], where + ".id");
    if (ji.contains("category"))
      seq.category = String(path, ji["category"], where + ".category");
    const json& jf = ji["frames"];
    if (!jf.is_array())
      ThrowInputError(path, where, ".frames must be an array");
    for (size_t k = 0; k < jf.size(); ++k) {
      const json& e = jf[k];
      const std::string fw = where + ".frames[" + std::to_string(k) + "]";
      if (!e.is_object()) ThrowInputError(path, fw, " must be an object");
      CheckKeys(path, e, fw, {"frame", "box_2d", "box_3d", "visibility"});
      if (!e.contains("frame")) ThrowInputError(path, fw, " needs \"frame\"");
      BoxFrame f;
      f.frame = Integer(path, e["frame"], fw + ".frame", 0, kMaxFrames);
      if (e.contains("box_2d")) {
        const Eigen::Vector4d b =
            JsonVector<4>(path, e["box_2d"], fw + ".box_2d");
        f.box_2d = Box2d{b[0], b[1], b[2], b[3]};
      }
      if (e.contains("box_3d")) {
        const json& b = e["box_3d"];
        if (!b.is_object())
          ThrowInputError(path, fw, ".box_3d must be an object");
        CheckKeys(path, b, fw + ".box_3d", {"center", "size", "rotation_wxyz"});
        for (const char* key : {"center", "size", "rotation_wxyz"}) {
          if (!b.contains(key))
            ThrowInputError(path, fw, ".box_3d: missing \"", key, "\"");
        }
        Box3d box;
        box.center = JsonVector<3>(path, b["center"], fw + ".box_3d.center");
        box.size = JsonVector<3>(path, b["size"], fw + ".box_3d.size");
        const Eigen::Vector4d q = JsonVector<4>(path, b["rotation_wxyz"],
                                                fw + ".box_3d.rotation_wxyz");
        if (std::abs(q.norm() - 1.0) > 1e-3)
          ThrowInputError(path, fw, ".box_3d.rotation_wxyz has norm ", q.norm(),
                          " (need a unit quaternion, scalar first)");
        box.rotation = QuaternionFromWxyz(q.normalized());
        f.box_3d = box;
      }
      if (e.contains("visibility"))
        f.visibility = JsonNumber(path, e["visibility"], fw + ".visibility");
      seq.frames.push_back(f);
    }
    boxes.instances.push_back(std::move(seq));
  }
  boxes.Check(path);
  return boxes;
}

void WriteBoxesJson(const std::string& path, const BoxSequences& boxes) {
  boxes.Check(path);
  json root;
  root["format"] = "geodrive-boxes";
  root["version"] = 1;
  root["image_width"] = boxes.image_width;
  root["image_height"] = boxes.image_height;
  root["num_frames"] = boxes.num_frames;
  root["units"] = boxes.units;
  json instances = json::array();
  for (const BoxSequence& s : boxes.instances) {
    json ji;
    ji["id"] = s.id;
    if (!s.category.empty()) ji["category"] = s.category;
    json frames = json::array();
    for (const BoxFrame& f : s.frames) {
      json e;
      e["frame"] = f.frame;
      if (f.box_2d)
        e["box_2d"] = {f.box_2d->xmin, f.box_2d->ymin, f.box_2d->xmax,
                       f.box_2d->ymax};
      if (f.box_3d) {
        e["box_3d"] = {{"center", VectorJson(f.box_3d->center)},
                       {"size", VectorJson(f.box_3d->size)},
                       {"rotation_wxyz",
                        VectorJson(QuaternionToWxyz(f.box_3d->rotation))}};
      }
      if (f.visibility) e["visibility"] = *f.visibility;
      frames.push_back(std::move(e));
    }
    ji["frames"] = std::move(frames);
    instances.push_back(std::move(ji));
  }
  root["instances"] = std::move(instances);
  WriteFileAtomic(path, root.dump(1) + "\n");
}

}  // namespace geodrive
