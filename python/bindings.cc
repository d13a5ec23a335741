// geodrive._core: the toolkit's core in Python over NumPy arrays (pybind11).
//
// Conventions: poses are (T, 4, 4) float64 matrices, world_from_cam unless a
// name says otherwise; cameras are (3, 3) K in integer-index pixels (OpenCV);
// images are (H, W, 3) uint8 RGB. Results are NumPy arrays that own their
// buffers. Every heavy call releases the GIL.
//
// Paths are PathArg: str, bytes or os.PathLike, UTF-8 without NUL bytes.
// C++ exceptions become one-line Python errors (TranslateException): InputError
// -> ValueError, out of memory -> MemoryError, std::filesystem errors ->
// OSError naming the paths, anything else -> RuntimeError. Arguments pybind11
// cannot convert are explained by geodrive/_args.py (a TypeError or
// ValueError naming the argument). Forked children render serially
// (ForkedChildRunsOpenMPSerially).

#include <omp.h>
#include <pthread.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Geometry>
#include <cstring>
#include <filesystem>
#include <memory>
#include <new>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "dataset/drive_dataset.h"
#include "dataset/pairs.h"
#include "dataset/scene_source.h"
#include "eval/image_metrics.h"
#include "eval/trajectory_metrics.h"
#include "geometry/alignment.h"
#include "geometry/reconstruction.h"
#include "geometry/trajectory_edit.h"
#include "geometry/trajectory_json.h"
#include "geometry/util/status.h"
#include "planning/candidates.h"
#include "planning/clip_scene.h"
#include "planning/plan_json.h"
#include "planning/scores.h"
#include "render/boxes.h"
#include "render/dynamic_edit.h"
#include "render/renderer.h"
#include "render/video/video_io.h"

namespace py = pybind11;

namespace geodrive {
namespace {

// A path argument (see type_caster<PathArg> below).
struct PathArg {
  std::string value;
};

}  // namespace
}  // namespace geodrive

namespace pybind11::detail {

// PathArg from str, bytes or os.PathLike (pathlib.Path): os.fspath(), then
// UTF-8 without NUL bytes; anything else does not load (geodrive/_args.py
// then names the argument and what is wrong with it).
template <>
struct type_caster<geodrive::PathArg> {
  PYBIND11_TYPE_CASTER(geodrive::PathArg, const_name("os.PathLike"));

  bool load(handle src, bool /*convert*/) {
    object fs = reinterpret_steal<object>(PyOS_FSPath(src.ptr()));
    if (!fs) {
      PyErr_Clear();
      return false;
    }
    const char* data = nullptr;
    Py_ssize_t size = 0;
    object utf8;
    if (PyUnicode_Check(fs.ptr())) {
      data = PyUnicode_AsUTF8AndSize(fs.ptr(), &size);  // fails on surrogates
    } else {
      char* bytes = nullptr;
      if (PyBytes_AsStringAndSize(fs.ptr(), &bytes, &size) == 0) {
        utf8 = reinterpret_steal<object>(
            PyUnicode_DecodeUTF8(bytes, size, "strict"));
        if (utf8) data = bytes;
      }
    }
    if (!data) {
      PyErr_Clear();
      return false;
    }
    if (std::memchr(data, 0, static_cast<size_t>(size)) != nullptr)
      return false;
    value.value.assign(data, static_cast<size_t>(size));
    return true;
  }

  static handle cast(const geodrive::PathArg& path,
                     return_value_policy /*policy*/,
                     handle /*parent*/) {
    return PyUnicode_DecodeUTF8(path.value.data(),
                                static_cast<Py_ssize_t>(path.value.size()),
                                "strict");
  }
};

}  // namespace pybind11::detail

namespace geodrive {
namespace {

template <typename T>
using CArray = py::array_t<T, py::array::c_style | py::array::forcecast>;

// ---- NumPy <-> toolkit types ----

void CheckShape(const py::array& a,
                std::vector<py::ssize_t> shape,
                const char* what) {
  bool ok = a.ndim() == static_cast<py::ssize_t>(shape.size());
  for (size_t i = 0; ok && i < shape.size(); ++i)
    ok = shape[i] < 0 || a.shape(i) == shape[i];
  if (!ok) {
    std::string want = "(", have = "(";
    for (size_t i = 0; i < shape.size(); ++i)
      want += (i ? ", " : "") +
              (shape[i] < 0 ? std::string("N") : std::to_string(shape[i]));
    for (py::ssize_t i = 0; i < a.ndim(); ++i)
      have += (i ? ", " : "") + std::to_string(a.shape(i));
    ThrowInputError(what, "shape ", have, "), expected ", want, ")");
  }
}

Rigid3d PoseFromArray(const double* m, const char* what) {
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) M(r, c) = m[r * 4 + c];
  GEODRIVE_CHECK_INPUT(M.allFinite(), what, ": pose is not finite");
  return Rigid3d::FromMatrix(M, 1e-4);
}

std::vector<Rigid3d> Poses(const CArray<double>& poses, const char* what) {
  if (poses.ndim() == 2) {
    CheckShape(poses, {4, 4}, what);
    return {PoseFromArray(poses.data(), what)};
  }
  CheckShape(poses, {-1, 4, 4}, what);
  std::vector<Rigid3d> out;
  for (py::ssize_t i = 0; i < poses.shape(0); ++i)
    out.push_back(PoseFromArray(poses.data() + 16 * i, what));
  return out;
}

CArray<double> PosesToArray(const std::vector<Rigid3d>& poses) {
  CArray<double> out(
      {static_cast<py::ssize_t>(poses.size()), py::ssize_t{4}, py::ssize_t{4}});
  double* p = out.mutable_data();
  for (const Rigid3d& pose : poses) {
    const Eigen::Matrix4d m = pose.ToMatrix();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) *p++ = m(r, c);
  }
  return out;
}

Trajectory TrajectoryFrom(const CArray<double>& poses,
                          const std::optional<CArray<double>>& times,
                          const char* what) {
  const std::vector<Rigid3d> p = Poses(poses, what);
  Trajectory t;
  for (size_t i = 0; i < p.size(); ++i) {
    double stamp = static_cast<double>(i);
    if (times) {
      GEODRIVE_CHECK_INPUT(
          times->ndim() == 1 &&
              times->shape(0) == static_cast<py::ssize_t>(p.size()),
          what, ": times must be (T,) like the poses");
      stamp = times->data()[i];
    }
    t.Add(stamp, p[i]);
  }
  return t;
}

CArray<double> MatrixToArray(const Eigen::Matrix3d& K) {
  CArray<double> out({py::ssize_t{3}, py::ssize_t{3}});
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out.mutable_data()[r * 3 + c] = K(r, c);
  return out;
}

PinholeCamera CameraFrom(const CArray<double>& K, int width, int height) {
  CheckShape(K, {3, 3}, "K");
  const double* k = K.data();
  GEODRIVE_CHECK_INPUT(
      k[1] == 0 && k[3] == 0 && k[6] == 0 && k[7] == 0 && k[8] == 1, "K",
      ": expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]");
  PinholeCamera c(k[0], k[4], k[2], k[5], width, height);
  c.Check("K");
  return c;
}

// Colours and images are uint8 in 0..255, and nothing else is converted to
// them: a float array in [0, 1] would become black and one in 0..255 would
// be truncated, uint16 would wrap (the forcecast of CArray<uint8_t>). Any
// other dtype is a ValueError naming the argument and the conversion to make.
CArray<uint8_t> Uint8Array(const py::array& a, const char* what) {
  if (!a.dtype().is(py::dtype::of<uint8_t>())) {
    ThrowInputError(
        what, "dtype ", py::str(a.dtype()).cast<std::string>(),
        ", expected uint8 in 0..255 (floats in [0, 1]: "
        "(x * 255).round().astype(numpy.uint8); uint16: scale to 0..255 "
        "first)");
  }
  return CArray<uint8_t>::ensure(a);
}

// An (H, W, 3) uint8 or (H, W) image as a cv::Mat sharing the buffer.
cv::Mat ImageView(const CArray<uint8_t>& a, const char* what) {
  GEODRIVE_CHECK_INPUT((a.ndim() == 3 && a.shape(2) == 3) || a.ndim() == 2,
                       what, ": expected an (H, W, 3) or (H, W) uint8 image");
  return cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)),
                 a.ndim() == 3 ? CV_8UC3 : CV_8UC1,
                 const_cast<uint8_t*>(a.data()));
}

template <typename T>
CArray<T> MatToArray(const cv::Mat& m) {
  std::vector<py::ssize_t> shape = {m.rows, m.cols};
  if (m.channels() > 1) shape.push_back(m.channels());
  CArray<T> out(shape);
  const size_t row = static_cast<size_t>(m.cols) * m.channels() * sizeof(T);
  for (int r = 0; r < m.rows; ++r)
    std::memcpy(
        out.mutable_data() + static_cast<size_t>(r) * m.cols * m.channels(),
        m.ptr<T>(r), row);
  return out;
}

// ---- Datasets and clips ----

struct PyClip {
  DriveClip clip;
};

py::dict BoxToDict(const ClipBox& b) {
  py::dict d;
  d["instance_id"] = b.instance_id;
  d["category"] = b.category;
  d["center"] =
      std::vector<double>{b.box.center.x(), b.box.center.y(), b.box.center.z()};
  d["size_wlh"] =
      std::vector<double>{b.box.size.x(), b.box.size.y(), b.box.size.z()};
  d["world_from_box"] = PosesToArray({b.box.WorldFromBox()})[py::int_(0)];
  return d;
}

void BindDataset(py::module_& m) {
  py::class_<DriveDataset, std::shared_ptr<DriveDataset>>(
      m, "Dataset", "A driving dataset opened by open_dataset().")
      .def("describe", &DriveDataset::Describe,
           "One line: format, version, root, scene and clip counts.")
      .def_property_readonly(
          "clip_ids", [](const DriveDataset& d) { return d.ClipIds(); },
          "Clip ids in dataset order (scene, then start frame).")
      .def_property_readonly("has_lidar", &DriveDataset::HasLidar)
      .def(
          "scenes",
          [](const DriveDataset& d) {
            std::vector<std::string> scenes;
            for (const std::string& id : d.ClipIds()) {
              const std::string s = id.substr(0, id.find('_'));
              if (scenes.empty() || scenes.back() != s) scenes.push_back(s);
            }
            return scenes;
          },
          "Scene names, in order (the part of each clip id before '_').")
      .def(
          "load_clip",
          [](const DriveDataset& d, const std::string& id) {
            py::gil_scoped_release release;
            return PyClip{d.LoadClip(id)};
          },
          py::arg("clip_id"),
          "The clip: frames, poses, cameras, boxes and its LiDAR sweeps.");

  m.def(
      "open_dataset",
      [](const PathArg& root, const std::string& version,
         const std::string& frames, const std::string& channel, int clip_frames,
         int stride, const std::string& dataset) {
        DriveDatasetOptions o;
        o.format = ResolveDatasetFormat(dataset, root.value);
        o.root = root.value;
        o.version = version;
        o.frames = ParseClipFrameSource(frames);
        o.channel = channel;
        o.clip_frames = clip_frames;
        o.clip_stride = stride;
        py::gil_scoped_release release;
        return std::shared_ptr<DriveDataset>(OpenDriveDataset(o));
      },
      py::arg("root"), py::arg("version") = "v1.0-mini",
      py::arg("frames") = "all", py::arg("channel") = "CAM_FRONT",
      py::arg("clip_frames") = 25, py::arg("stride") = 6,
      py::arg("dataset") = "auto",
      "Opens a driving dataset: nuScenes tables (frames='keyframes' for "
      "extracts without sweep files) or a folder of Waymo v1 *.tfrecord "
      "segments (channel 'CAM_FRONT' reads Waymo's FRONT); dataset='auto' "
      "tells them apart, or 'nuscenes' / 'waymo'.");
}

// The clip: frames, poses, cameras, boxes, LiDAR sweeps.
void BindClip(py::module_& m) {
  py::class_<PyClip>(m, "Clip", "One clip (DriveClip of dataset/drive_clip.h).")
      .def_property_readonly("id", [](const PyClip& c) { return c.clip.id; })
      .def_property_readonly("scene_name",
                             [](const PyClip& c) { return c.clip.scene_name; })
      .def_property_readonly(
          "num_frames", [](const PyClip& c) { return c.clip.num_frames(); })
      .def_property_readonly(
          "timestamps_us",
          [](const PyClip& c) {
            CArray<int64_t> t({static_cast<py::ssize_t>(c.clip.num_frames())});
            for (int i = 0; i < c.clip.num_frames(); ++i)
              t.mutable_data()[i] = c.clip.frames[i].timestamp_us;
            return t;
          },
          "(T,) int64 capture times in microseconds.")
      .def_property_readonly("image_paths",
                             [](const PyClip& c) {
                               std::vector<std::string> p;
                               for (const DriveFrame& f : c.clip.frames)
                                 p.push_back(f.image_path);
                               return p;
                             })
      .def_property_readonly(
          "world_from_cam",
          [](const PyClip& c) {
            std::vector<Rigid3d> p;
            for (const DriveFrame& f : c.clip.frames)
              p.push_back(f.world_from_cam);
            return PosesToArray(p);
          },
          "(T, 4, 4) camera-to-world poses (ego pose ∘ calibration), metres.")
      .def_property_readonly("world_from_ego",
                             [](const PyClip& c) {
                               std::vector<Rigid3d> p;
                               for (const DriveFrame& f : c.clip.frames)
                                 p.push_back(f.world_from_ego);
                               return PosesToArray(p);
                             })
      .def_property_readonly(
          "intrinsics",
          [](const PyClip& c) {
            CArray<double> K({static_cast<py::ssize_t>(c.clip.num_frames()),
                              py::ssize_t{3}, py::ssize_t{3}});
            for (int i = 0; i < c.clip.num_frames(); ++i) {
              const Eigen::Matrix3d k = c.clip.frames[i].camera.K();
              for (int r = 0; r < 3; ++r)
                for (int col = 0; col < 3; ++col)
                  K.mutable_data()[9 * i + 3 * r + col] = k(r, col);
            }
            return K;
          },
          "(T, 3, 3) K at the source image size, integer-index pixels.")
      .def_property_readonly(
          "image_size",
          [](const PyClip& c) {
            const PinholeCamera& cam = c.clip.frames.front().camera;
            return std::make_pair(cam.width, cam.height);
          },
          "(width, height) of the source images.")
      .def(
          "boxes",
          [](const PyClip& c, int frame) {
            GEODRIVE_CHECK_INPUT(frame >= 0 && frame < c.clip.num_frames(),
                                 "frame ", frame, " out of range");
            py::list out;
            for (const ClipBox& b : c.clip.frames[frame].boxes)
              out.append(BoxToDict(b));
            return out;
          },
          py::arg("frame"),
          "Boxes at frame `frame`: dicts with instance_id, category, center "
          "(world, m), size_wlh, world_from_box (4, 4).")
      .def(
          "lidar_sweeps",
          [](const PyClip& c) {
            GEODRIVE_CHECK_INPUT(c.clip.lidar, c.clip.id,
                                 ": the dataset has no LiDAR");
            py::list out;
            for (const LidarSweepInfo& s : c.clip.lidar->Sweeps()) {
              py::dict d;
              d["timestamp_us"] = s.timestamp_us;
              d["path"] = s.relative_path;
              d["world_from_sensor"] =
                  PosesToArray({s.WorldFromSensor()})[py::int_(0)];
              out.append(d);
            }
            return out;
          },
          "The scene's LiDAR sweeps (metadata), in time order.")
      .def(
          "load_sweep",
          [](const PyClip& c, size_t index) {
            GEODRIVE_CHECK_INPUT(c.clip.lidar, c.clip.id,
                                 ": the dataset has no LiDAR");
            GEODRIVE_CHECK_INPUT(index < c.clip.lidar->Sweeps().size(),
                                 "sweep ", index, " out of range");
            PointCloud cloud;
            {
              py::gil_scoped_release release;
              cloud = c.clip.lidar->Load(index);
            }
            CArray<float> out(
                {static_cast<py::ssize_t>(cloud.size()), py::ssize_t{5}});
            float* p = out.mutable_data();
            for (size_t i = 0; i < cloud.size(); ++i) {
              p[5 * i + 0] = cloud.positions[i].x();
              p[5 * i + 1] = cloud.positions[i].y();
              p[5 * i + 2] = cloud.positions[i].z();
              p[5 * i + 3] = cloud.HasIntensity() ? cloud.intensity[i] : 0.f;
              p[5 * i + 4] = cloud.HasRing() ? cloud.ring[i] : 0.f;
            }
            return out;
          },
          py::arg("index"),
          "Sweep `index` as an (N, 5) float32 array: x, y, z (sensor frame, "
          "m), intensity, ring.");
}

// ---- Scenes ----

struct PyScene {
  ConditionScene scene;
};

void BindScenes(py::module_& m) {
  py::class_<PyScene>(m, "ConditionScene",
                      "The geometry a condition is rendered from.")
      .def_property_readonly(
          "points",
          [](const PyScene& s) {
            CArray<float> out({static_cast<py::ssize_t>(s.scene.cloud.size()),
                               py::ssize_t{3}});
            float* p = out.mutable_data();
            for (const Eigen::Vector3f& x : s.scene.cloud.positions)
              *p++ = x.x(), *p++ = x.y(), *p++ = x.z();
            return out;
          },
          "(N, 3) float32 points in the scene frame.")
      .def_property_readonly(
          "colors",
          [](const PyScene& s) {
            CArray<uint8_t> out({static_cast<py::ssize_t>(s.scene.cloud.size()),
                                 py::ssize_t{3}});
            uint8_t* p = out.mutable_data();
            if (s.scene.cloud.HasColors()) {
              for (const Color3u8& c : s.scene.cloud.colors)
                *p++ = c[0], *p++ = c[1], *p++ = c[2];
            } else {
              std::memset(p, 0, s.scene.cloud.size() * 3);
            }
            return out;
          },
          "(N, 3) uint8 RGB.")
      .def_property_readonly(
          "footprints",
          [](const PyScene& s) -> std::optional<CArray<float>> {
            const PointCloud& c = s.scene.cloud;
            if (!c.HasFootprints()) return std::nullopt;
            CArray<float> out({static_cast<py::ssize_t>(c.size())});
            std::copy(c.footprints.begin(), c.footprints.end(),
                      out.mutable_data());
            return out;
          },
          "(N,) float32 capture footprints (the side of the pixel that saw "
          "each point, in scene units; render(..., footprints=) draws points "
          "seen closer than at capture over their magnified footprint), or "
          "None.")
      .def_property_readonly(
          "footprint_axes",
          [](const PyScene& s) -> std::optional<CArray<float>> {
            const PointCloud& c = s.scene.cloud;
            if (c.footprint_u.empty()) return std::nullopt;
            CArray<float> out(
                {static_cast<py::ssize_t>(c.size()), py::ssize_t{6}});
            float* p = out.mutable_data();
            for (size_t i = 0; i < c.size(); ++i) {
              for (int k = 0; k < 3; ++k) p[6 * i + k] = c.footprint_u[i][k];
              for (int k = 0; k < 3; ++k)
                p[6 * i + 3 + k] = c.footprint_v[i][k];
            }
            return out;
          },
          "(N, 6) float32: each capture pixel as a surface patch, its "
          "displacement per capture pixel along x (first 3) and y (last 3) "
          "in scene units; or None (then square footprints).")
      .def_property_readonly(
          "poses",
          [](const PyScene& s) {
            return PosesToArray(s.scene.trajectory.world_from_cam);
          },
          "(T, 4, 4) scene_from_cam of the source's frames.")
      .def_property_readonly(
          "K",
          [](const PyScene& s) { return MatrixToArray(s.scene.camera.K()); },
          "(3, 3) frame-0 K on the source's own grid (see image_size).")
      .def_property_readonly("image_size",
                             [](const PyScene& s) {
                               return std::make_pair(s.scene.camera.width,
                                                     s.scene.camera.height);
                             })
      .def(
          "K_at",
          [](const PyScene& s, int width, int height) {
            return MatrixToArray(
                s.scene.CameraAt(width, height, ResizeMode::kResize).K());
          },
          py::arg("width"), py::arg("height"),
          "K for a render of width x height (the source grid resized).")
      .def_property_readonly("units",
                             [](const PyScene& s) { return s.scene.units; })
      .def_property_readonly(
          "description", [](const PyScene& s) { return s.scene.description; })
      .def_property_readonly("scale_report", [](const PyScene& s) {
        return s.scene.scale.report;
      });

  m.def(
      "scene_sources", [] { return SceneSourceNames(); },
      "The registered scene sources (monst3r, lidar, lidar-dense, vggt, ...).");
  m.def(
      "condition_scene",
      [](const std::string& source, const PathArg& path, const PyClip* clip,
         const std::string& filter) {
        SceneInputs in;
        in.path = path.value;
        in.clip = clip ? &clip->clip : nullptr;
        SceneSourceOptions o;
        GEODRIVE_CHECK_INPUT(filter == "paper" || filter == "released",
                             "filter", ": '", filter,
                             "' is not one of paper, released");
        o.filter = filter == "paper" ? PointmapFilter::kPaper
                                     : PointmapFilter::kReleased;
        py::gil_scoped_release release;
        return PyScene{BuildConditionScene(source, in, o)};
      },
      py::arg("source"), py::arg("path") = "", py::arg("clip") = nullptr,
      py::arg("filter") = "paper",
      "Builds a scene source's ConditionScene: source is a name of "
      "scene_sources(); path its input (a MonST3R folder, a VGGT npz, ...); "
      "clip the clip it is built for (LiDAR scale, lidar sources).");
  m.def(
      "reconstruction_format",
      [](const PathArg& path) -> std::optional<std::string> {
        const auto f = DetectReconstructionFormat(path.value);
        if (!f) return std::nullopt;
        return ToString(*f);
      },
      py::arg("path"),
      "The reconstruction format of a file or folder (vggt, da3, ...) or "
      "None.");
}

// ---- Rendering and trajectories ----

// render()'s output: renders `cloud` from each of `poses` straight into numpy
// arrays, those of `out` (a previous result of the same shapes: rendered in
// place, as a C++ loop reuses its frames) or fresh ones, and returns them as
// {'rgb', 'depth', 'valid'}.
py::dict RenderIntoArrays(const PointCloud& cloud,
                          const PinholeCamera& camera,
                          const std::vector<Rigid3d>& poses,
                          const RenderOptions& o,
                          const py::object& out) {
  const py::ssize_t T = static_cast<py::ssize_t>(poses.size());
  const int H = o.height, W = o.width;
  py::array_t<uint8_t> rgb;
  py::array_t<float> depth;
  py::array_t<bool> valid;
  const std::vector<py::ssize_t> image = {T, H, W};
  auto fits = [&](const py::array& a, std::vector<py::ssize_t> shape) {
    if (a.ndim() != static_cast<py::ssize_t>(shape.size()) ||
        !(a.flags() & py::array::c_style) || !a.writeable())
      return false;
    for (size_t i = 0; i < shape.size(); ++i)
      if (a.shape(i) != shape[i]) return false;
    return true;
  };
  bool reuse = false;
  if (!out.is_none()) {
    GEODRIVE_CHECK_INPUT(py::isinstance<py::dict>(out), "out",
                         ": expected a previous render() result");
    py::dict d = out.cast<py::dict>();
    reuse = d.contains("rgb") && d.contains("depth") && d.contains("valid") &&
            py::isinstance<py::array_t<uint8_t>>(d["rgb"]) &&
            py::isinstance<py::array_t<float>>(d["depth"]) &&
            py::isinstance<py::array_t<bool>>(d["valid"]);
    if (reuse) {
      rgb = d["rgb"].cast<py::array_t<uint8_t>>();
      depth = d["depth"].cast<py::array_t<float>>();
      valid = d["valid"].cast<py::array_t<bool>>();
      reuse =
          fits(rgb, {T, H, W, 3}) && fits(depth, image) && fits(valid, image);
    }
    GEODRIVE_CHECK_INPUT(reuse, "out",
                         ": its arrays do not match this render (", T,
                         " frames of ", H, "x", W, ")");
  } else {
    rgb = py::array_t<uint8_t>(
        {T, py::ssize_t{H}, py::ssize_t{W}, py::ssize_t{3}});
    depth = py::array_t<float>(image);
    valid = py::array_t<bool>(image);
  }
  uint8_t* rgb_p = rgb.mutable_data();
  float* depth_p = depth.mutable_data();
  // numpy bool is one byte: the renderer's mask (0 / 255) is written there,
  // then folded to 0 / 1.
  uint8_t* valid_p = reinterpret_cast<uint8_t*>(valid.mutable_data());
  {
    py::gil_scoped_release release;
    const size_t px = static_cast<size_t>(H) * W;
    RenderResult r;
    r.frames.resize(T);
    for (py::ssize_t t = 0; t < T; ++t) {
      r.frames[t].rgb = cv::Mat(H, W, CV_8UC3, rgb_p + t * px * 3);
      r.frames[t].depth = cv::Mat(H, W, CV_32F, depth_p + t * px);
      r.frames[t].mask = cv::Mat(H, W, CV_8U, valid_p + t * px);
    }
    RenderFramesInto(cloud, {camera}, poses, o, &r);
    for (py::ssize_t t = 0; t < T; ++t) {    // in place, unless the
      const RenderedFrame& f = r.frames[t];  // renderer reallocated
      if (f.rgb.data != rgb_p + t * px * 3)
        std::memcpy(rgb_p + t * px * 3, f.rgb.data, px * 3);
      if (f.depth.data != reinterpret_cast<uint8_t*>(depth_p + t * px))
        std::memcpy(depth_p + t * px, f.depth.data, px * sizeof(float));
      if (f.mask.data != valid_p + t * px)
        std::memcpy(valid_p + t * px, f.mask.data, px);
    }
    for (size_t i = 0; i < px * T; ++i) valid_p[i] = valid_p[i] != 0;
  }
  py::dict result;
  result["rgb"] = rgb;
  result["depth"] = depth;
  result["valid"] = valid;
  return result;
}

void BindRender(py::module_& m) {
  m.def(
      "render",
      [](const CArray<float>& points, const py::array& colors_in,
         const CArray<double>& K, const CArray<double>& cam_from_world,
         std::pair<int, int> size, const std::string& mode, double radius,
         double near, double far, int threads, py::object out,
         std::optional<CArray<float>> footprints,
         std::optional<CArray<float>> footprint_axes,
         double max_magnification) {
        CheckShape(points, {-1, 3}, "points");
        const CArray<uint8_t> colors = Uint8Array(colors_in, "colors");
        CheckShape(colors, {points.shape(0), 3}, "colors");
        const int H = size.first, W = size.second;
        RenderOptions o;
        o.mode = ParseRenderMode(mode);
        o.width = W;
        o.height = H;
        o.radius_px = radius;
        o.near = near;
        o.far = far;
        o.num_threads = threads;
        if (footprints) {
          CheckShape(*footprints, {points.shape(0)}, "footprints");
          o.splat_size = SplatSize::kFootprint;
          o.max_footprint_magnification = max_magnification;
        }
        o.Check();
        const PinholeCamera camera = CameraFrom(K, W, H);
        const std::vector<Rigid3d> poses =
            Poses(cam_from_world, "cam_from_world");
        PointCloud cloud;
        cloud.positions.resize(points.shape(0));
        cloud.colors.resize(points.shape(0));
        const float* pp = points.data();
        const uint8_t* cp = colors.data();
        for (py::ssize_t i = 0; i < points.shape(0); ++i) {
          cloud.positions[i] =
              Eigen::Vector3f(pp[3 * i], pp[3 * i + 1], pp[3 * i + 2]);
          cloud.colors[i] = Color3u8(cp[3 * i], cp[3 * i + 1], cp[3 * i + 2]);
        }
        if (footprints)
          cloud.footprints.assign(footprints->data(),
                                  footprints->data() + points.shape(0));
        if (footprint_axes) {
          GEODRIVE_CHECK_INPUT(footprints.has_value(), "footprint_axes",
                               ": given without footprints");
          CheckShape(*footprint_axes, {points.shape(0), 6}, "footprint_axes");
          cloud.footprint_u.resize(points.shape(0));
          cloud.footprint_v.resize(points.shape(0));
          const float* a = footprint_axes->data();
          for (py::ssize_t i = 0; i < points.shape(0); ++i) {
            cloud.footprint_u[i] =
                Eigen::Vector3f(a[6 * i], a[6 * i + 1], a[6 * i + 2]);
            cloud.footprint_v[i] =
                Eigen::Vector3f(a[6 * i + 3], a[6 * i + 4], a[6 * i + 5]);
          }
        }
        return RenderIntoArrays(cloud, camera, poses, o, out);
      },
      py::arg("points"), py::arg("colors"), py::arg("K"),
      py::arg("cam_from_world"), py::arg("size") = std::make_pair(480, 720),
      py::arg("mode") = "zbuffer", py::arg("radius") = 0.0,
      py::arg("near") = 0.1, py::arg("far") = 100.0, py::arg("threads") = 0,
      py::arg("out") = py::none(), py::arg("footprints") = py::none(),
      py::arg("footprint_axes") = py::none(),
      py::arg("max_magnification") = 8.0,
      "Renders (N, 3) float32 points with (N, 3) uint8 colours through K "
      "(3, 3, for the output size) from each (4, 4) pose of cam_from_world "
      "(T, 4, 4). size = (H, W). Returns {'rgb': (T, H, W, 3) uint8, "
      "'depth': (T, H, W) float32 (0 = none), 'valid': (T, H, W) bool}; "
      "out= a previous result of the same shapes renders into its arrays "
      "(no fresh allocation, as a loop over clips wants). footprints= (N,) "
      "capture footprints (ConditionScene.footprints, with its "
      "footprint_axes when it has them) gives the footprint preset: points "
      "seen closer than at capture cover their magnified capture pixel, up "
      "to max_magnification (z-buffer mode).");
}

// Rendering with dynamic editing along box sequences.
void BindEditedRender(py::module_& m) {
  m.def(
      "render_with_edits",
      [](const CArray<float>& points, const py::array& colors_in,
         const CArray<double>& K, const CArray<double>& cam_from_world,
         const PathArg& boxes_json, std::pair<int, int> size,
         const std::string& mode, const std::vector<std::string>& remove,
         double radius, std::optional<py::array> frame0_image) {
        CheckShape(points, {-1, 3}, "points");
        const CArray<uint8_t> colors = Uint8Array(colors_in, "colors");
        CheckShape(colors, {points.shape(0), 3}, "colors");
        const int H = size.first, W = size.second;
        RenderOptions ro;
        ro.width = W;
        ro.height = H;
        ro.radius_px = radius;
        ro.output_instance = true;
        ro.Check();
        DynamicEditOptions eo;
        GEODRIVE_CHECK_INPUT(mode == "3d" || mode == "2d", "mode", ": '", mode,
                             "' is not one of 3d, 2d");
        eo.mode = mode == "3d" ? EditMode::k3d : EditMode::k2d;
        if (frame0_image)
          eo.frame0_image = ImageView(Uint8Array(*frame0_image, "frame0_image"),
                                      "frame0_image")
                                .clone();
        const PinholeCamera camera = CameraFrom(K, W, H);
        const std::vector<Rigid3d> poses =
            Poses(cam_from_world, "cam_from_world");
        const BoxSequences boxes = ReadBoxesJson(boxes_json.value);
        std::vector<ObjectEdit> edits;
        for (const std::string& id : remove) {
          ObjectEdit e;
          e.kind = ObjectEditKind::kRemove;
          e.instance = id;
          edits.push_back(e);
        }
        PointCloud cloud;
        cloud.positions.resize(points.shape(0));
        cloud.colors.resize(points.shape(0));
        for (py::ssize_t i = 0; i < points.shape(0); ++i) {
          const float* p = points.data() + 3 * i;
          const uint8_t* c = colors.data() + 3 * i;
          cloud.positions[i] = Eigen::Vector3f(p[0], p[1], p[2]);
          cloud.colors[i] = Color3u8(c[0], c[1], c[2]);
        }
        const py::ssize_t T = static_cast<py::ssize_t>(poses.size());
        CArray<uint8_t> rgb(
            {T, py::ssize_t{H}, py::ssize_t{W}, py::ssize_t{3}});
        CArray<int32_t> instance({T, py::ssize_t{H}, py::ssize_t{W}});
        py::array_t<bool> valid({T, py::ssize_t{H}, py::ssize_t{W}});
        std::vector<std::string> render_ids;
        {
          py::gil_scoped_release release;
          DynamicEditResult r = RenderWithDynamicEdits(cloud, {camera}, poses,
                                                       boxes, edits, eo, ro);
          const size_t px = static_cast<size_t>(H) * W;
          for (py::ssize_t t = 0; t < T; ++t) {
            const RenderedFrame& f = r.frames[t];
            std::memcpy(rgb.mutable_data() + t * px * 3, f.rgb.data, px * 3);
            std::memcpy(instance.mutable_data() + t * px, f.instance.data,
                        px * sizeof(int32_t));
            for (size_t i = 0; i < px; ++i)
              valid.mutable_data()[t * px + i] = f.mask.data[i] != kMaskInvalid;
          }
          render_ids = r.render_ids;
        }
        py::dict out;
        out["rgb"] = rgb;
        out["valid"] = valid;
        out["instance"] = instance;
        out["render_ids"] = render_ids;
        return out;
      },
      py::arg("points"), py::arg("colors"), py::arg("K"),
      py::arg("cam_from_world"), py::arg("boxes"),
      py::arg("size") = std::make_pair(480, 720), py::arg("mode") = "3d",
      py::arg("remove") = std::vector<std::string>(), py::arg("radius") = 0.0,
      py::arg("frame0_image") = py::none(),
      "Renders with dynamic editing (render/dynamic_edit.h): the objects of "
      "the box sequences in `boxes` (a boxes.json path, e.g. a pair's) move "
      "along their boxes (3d) or are pasted from frame0_image (2d); "
      "`remove` lists instance ids to drop. Returns {'rgb', 'valid', "
      "'instance' (T, H, W) int32 render id (-1 = background), "
      "'render_ids' (render id -> instance id)}.");
}

// Trajectory edits and readers.
void BindTrajectories(py::module_& m) {
  m.def(
      "edit_trajectory",
      [](const CArray<double>& world_from_cam,
         const std::optional<CArray<double>>& times, double shift_left,
         double shift_right, double shift_up, double yaw_deg, double speed,
         bool reverse) {
        Trajectory t = TrajectoryFrom(world_from_cam, times, "world_from_cam");
        if (shift_left != 0) t = ShiftLeft(t, shift_left);
        if (shift_right != 0) t = ShiftRight(t, shift_right);
        if (shift_up != 0) t = ShiftUp(t, shift_up);
        if (yaw_deg != 0) t = ApplyYawOffset(t, yaw_deg);
        GEODRIVE_CHECK_INPUT(speed > 0, "speed", ": must be > 0");
        if (speed != 1) t = ScaleSpeed(t, speed);
        if (reverse) t = ReverseOrder(t);
        return PosesToArray(t.world_from_cam);
      },
      py::arg("world_from_cam"), py::arg("times") = py::none(),
      py::arg("shift_left") = 0.0, py::arg("shift_right") = 0.0,
      py::arg("shift_up") = 0.0, py::arg("yaw_deg") = 0.0,
      py::arg("speed") = 1.0, py::arg("reverse") = false,
      "GeoDrive's trajectory edits (geometry/trajectory_edit.h) on (T, 4, 4) "
      "world_from_cam poses: shifts in the first camera's axes, a yaw "
      "offset (degrees, positive = left), a speed factor (times in seconds, "
      "default the frame index), the path driven backwards.");

  m.def(
      "read_trajectory",
      [](const PathArg& path) {
        const Trajectory t = ReadTrajectoryAny(path.value);
        CArray<double> times({static_cast<py::ssize_t>(t.size())});
        for (size_t i = 0; i < t.size(); ++i)
          times.mutable_data()[i] = t.timestamps[i];
        return std::make_pair(PosesToArray(t.world_from_cam), times);
      },
      py::arg("path"),
      "Reads any trajectory the CLI reads (TUM, MonST3R, KITTI, COLMAP "
      "images.txt, JSON, a reconstruction's camera track): (poses (T, 4, 4) "
      "world_from_cam, times (T,)).");
}

// ---- Metrics and pairs ----

// One camera of a surround-view pair (PairView) with its videos as ReadPair
// resolved them: the module's conventions (K (3, 3), poses (T, 4, 4)
// world_from_cam, image_size (width, height)).
py::dict PairViewDict(const PairView& v,
                      const std::string& gt_video,
                      const std::string& cond_video) {
  py::dict d;
  d["channel"] = v.channel;
  d["gt_video"] = gt_video;
  d["cond_video"] = cond_video;
  d["num_frames"] = static_cast<int>(v.frames.size());
  CArray<int64_t> t({static_cast<py::ssize_t>(v.frames.size())});
  for (size_t i = 0; i < v.frames.size(); ++i)
    t.mutable_data()[i] = v.frames[i].timestamp_us;
  d["timestamps_us"] = t;
  d["K"] = MatrixToArray(v.intrinsics.K());
  d["image_size"] = std::make_pair(v.intrinsics.width, v.intrinsics.height);
  d["world_from_cam"] = PosesToArray(v.world_from_cam);
  d["coverage"] = v.coverage;
  d["psnr_static"] = v.psnr_static;
  d["supported_fraction"] = v.supported_fraction;
  d["coverage_of_supported"] = v.coverage_of_supported;
  d["points_built"] = v.points_built;
  d["points_kept"] = v.points_kept;
  return d;
}

void BindMetrics(py::module_& m) {
  m.def(
      "psnr",
      [](const py::array& a_in, const py::array& b_in) {
        const CArray<uint8_t> a = Uint8Array(a_in, "a"),
                              b = Uint8Array(b_in, "b");
        const cv::Mat ma = ImageView(a, "a"), mb = ImageView(b, "b");
        py::gil_scoped_release release;
        return Psnr(ma, mb);
      },
      py::arg("a"), py::arg("b"), "PSNR (dB) of two uint8 images (peak 255).");
  m.def(
      "ssim",
      [](const py::array& a_in, const py::array& b_in) {
        const CArray<uint8_t> a = Uint8Array(a_in, "a"),
                              b = Uint8Array(b_in, "b");
        const cv::Mat ma = ImageView(a, "a"), mb = ImageView(b, "b");
        py::gil_scoped_release release;
        return Ssim(ma, mb);
      },
      py::arg("a"), py::arg("b"),
      "SSIM of two uint8 images, averaged over channels (skimage's "
      "gaussian_weights=True, sigma 1.5, channel_axis=-1).");
  m.def(
      "ade_fde",
      [](const CArray<double>& pred, const CArray<double>& gt,
         const std::string& align) {
        TrajectoryErrorOptions o;
        o.alignment = ParseAlignmentType(align);
        const Trajectory p = TrajectoryFrom(pred, std::nullopt, "pred");
        const Trajectory g = TrajectoryFrom(gt, std::nullopt, "gt");
        const TrajectoryErrors e = ComputeTrajectoryErrors(p, g, o);
        py::dict d;
        d["ade"] = e.ade;
        d["fde"] = e.fde;
        d["rmse"] = e.rmse;
        d["per_frame"] = e.per_frame;
        return d;
      },
      py::arg("pred"), py::arg("gt"), py::arg("align") = "none",
      "ADE/FDE of camera centres, (T, 4, 4) world_from_cam each; align: "
      "none, se3, sim3 or scale (evo's conventions).");

  m.def(
      "read_manifest",
      [](const PathArg& path) {
        py::list out;
        for (const ManifestEntry& e : ReadManifest(path.value))
          out.append(py::module_::import("json").attr("loads")(
              ManifestEntryToJson(e)));
        return out;
      },
      py::arg("path"), "The lines of a build's manifest.jsonl, as dicts.");
  m.def(
      "read_pair",
      [](const PathArg& build, const py::dict& entry) {
        // The manifest line goes back through the C++ reader, so Python
        // pairs pass the same checks as C++ ones (ReadPair: pair_dir inside
        // the build, meta.json's clip id, listed files present).
        const std::string line = py::module_::import("json")
                                     .attr("dumps")(entry)
                                     .cast<std::string>();
        const std::string& build_dir = build.value;
        const PairRecord r = ReadPair(
            build_dir,
            ManifestEntryFromJson(line, build_dir + "/manifest.jsonl"));
        py::dict out;
        out["dir"] = r.dir;
        out["gt_video"] = r.gt_video;
        out["cond_video"] = r.cond_video;
        out["num_frames"] = static_cast<int>(r.meta.frames.size());
        py::list cameras, views, seams;
        for (size_t k = 0; k < r.meta.views.size(); ++k) {
          const PairView& v = r.meta.views[k];
          cameras.append(v.channel);
          views.append(PairViewDict(v, r.view_gt_videos.at(k),
                                    r.view_cond_videos.at(k)));
        }
        for (const PairSeam& s : r.meta.seams) {
          py::dict d;
          d["camera_a"] = s.camera_a;
          d["camera_b"] = s.camera_b;
          d["overlap_pixels"] = s.overlap_pixels;
          d["agreeing_fraction"] = s.agreeing_fraction;
          seams.append(d);
        }
        out["cameras"] = cameras;
        out["views"] = views;
        out["seams"] = seams;
        return out;
      },
      py::arg("build_dir"), py::arg("entry"),
      "Checks a manifest line's pair (ReadPair) and returns its folder, video "
      "paths and frame count; for a surround-view pair also its cameras, "
      "views (per camera, reference first: videos, K, poses, quality) and "
      "seams (empty lists for a single-camera pair).");
  m.def(
      "read_meta_json",
      [](const PathArg& pair_dir) {
        return PairMetaToJson(ReadPairMeta(pair_dir.value));
      },
      py::arg("pair_dir"), "A pair's meta.json, validated, as JSON text.");
  m.def(
      "read_video",
      [](const PathArg& video) {
        const std::string& path = video.value;
        std::vector<cv::Mat> frames;
        {
          py::gil_scoped_release release;
          frames = ReadVideoFrames(path);
        }
        GEODRIVE_CHECK_INPUT(!frames.empty(), path, ": no frames");
        const int H = frames[0].rows, W = frames[0].cols;
        CArray<uint8_t> out({static_cast<py::ssize_t>(frames.size()),
                             py::ssize_t{H}, py::ssize_t{W}, py::ssize_t{3}});
        for (size_t t = 0; t < frames.size(); ++t) {
          GEODRIVE_CHECK_INPUT(frames[t].rows == H && frames[t].cols == W &&
                                   frames[t].type() == CV_8UC3,
                               path, ": frame ", t, " has another size");
          for (int r = 0; r < H; ++r)
            std::memcpy(out.mutable_data() + (t * H + r) * W * 3,
                        frames[t].ptr<uint8_t>(r), W * 3);
        }
        return out;
      },
      py::arg("path"),
      "Decodes a video (our FFmpeg reader) into (T, H, W, 3) uint8 RGB.");
}

// ---- Errors and fork safety ----

// Sets a Python `type` error with `message`, its bytes that are not UTF-8
// escaped (\xff): a message quoting a non-UTF-8 path or line still reads.
void SetPythonError(PyObject* type, const std::string& message) {
  py::object text = py::reinterpret_steal<py::object>(PyUnicode_DecodeUTF8(
      message.data(), static_cast<Py_ssize_t>(message.size()),
      "backslashreplace"));
  if (!text) {
    PyErr_Clear();
    text = py::str("(an undecodable error message)");
  }
  PyErr_SetObject(type, text.ptr());
}

// A path for an OSError: str, undecodable bytes as surrogates (os.fsdecode).
py::object PathOrNone(const std::filesystem::path& path) {
  if (path.empty()) return py::none();
  const std::string& s = path.native();
  PyObject* text = PyUnicode_DecodeFSDefaultAndSize(
      s.data(), static_cast<Py_ssize_t>(s.size()));
  if (!text) {
    PyErr_Clear();
    return py::none();
  }
  return py::reinterpret_steal<py::object>(text);
}

// "filesystem error: <what>: <reason> [p1] [p2]" -> "<what>: <reason>".
std::string FilesystemReason(const std::filesystem::filesystem_error& e) {
  std::string text = e.what();
  const std::string prefix = "filesystem error: ";
  if (text.compare(0, prefix.size(), prefix) == 0) text.erase(0, prefix.size());
  std::string suffix;
  if (!e.path1().empty()) suffix += " [" + e.path1().native() + "]";
  if (!e.path2().empty()) suffix += " [" + e.path2().native() + "]";
  if (!suffix.empty() && text.size() >= suffix.size() &&
      text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0)
    text.resize(text.size() - suffix.size());
  return text;
}

constexpr char kOutOfMemory[] =
    "out of memory (the call needs more memory than this process may use: "
    "try a smaller size, fewer frames or fewer threads)";

// The module's exception boundary: every C++ exception leaves as one line.
// InputError -> ValueError (its text); std::bad_alloc, std::length_error (a
// size beyond what a container can hold) -> MemoryError (kOutOfMemory);
// std::filesystem errors -> OSError(errno, reason, path1, None, path2), so
// FileNotFoundError / PermissionError name their paths; any other exception
// -> RuntimeError "internal error: <first line>". pybind11's own exceptions
// go on to its translator.
void TranslateException(std::exception_ptr p) {
  try {
    if (p) std::rethrow_exception(p);
  } catch (const py::builtin_exception&) {
    throw;
  } catch (const InputError& e) {
    SetPythonError(PyExc_ValueError, e.what());
  } catch (const std::bad_alloc&) {
    SetPythonError(PyExc_MemoryError, kOutOfMemory);
  } catch (const std::length_error&) {
    SetPythonError(PyExc_MemoryError, kOutOfMemory);
  } catch (const std::filesystem::filesystem_error& e) {
    const std::string reason = FilesystemReason(e);
    py::object error = py::reinterpret_borrow<py::object>(PyExc_OSError)(
        e.code().value(),
        py::reinterpret_steal<py::object>(PyUnicode_DecodeUTF8(
            reason.data(), static_cast<Py_ssize_t>(reason.size()),
            "backslashreplace")),
        PathOrNone(e.path1()), py::none(), PathOrNone(e.path2()));
    PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(error.ptr())),
                    error.ptr());
  } catch (const std::exception& e) {
    std::string text = e.what();
    text = "internal error: " + text.substr(0, text.find('\n'));
    SetPythonError(PyExc_RuntimeError, text);
  }
}

// Fork safety: libgomp keeps the threads of a thread's last parallel region
// for the next one, and fork() copies that bookkeeping but not the threads,
// so a forked child's first parallel region of more than one thread waits for
// them forever (multiprocessing's fork workers after a threads=2 render in
// the parent). The rule: in a forked child, the thread that called fork() --
// the child's only thread -- runs every OpenMP region on one thread
// (max-active-levels 0 overrides num_threads clauses). Threads the child
// starts itself have their own fresh OpenMP state; std::thread pools start
// their threads per call and are unaffected. Results do not depend on the
// thread count (the renderer draws each frame on one thread).
void ForkedChildRunsOpenMPSerially() { omp_set_max_active_levels(0); }

// ---- Planning ----

// A candidate from an (N, 4) array of waypoints t, x, y, yaw (ego0).
Candidate CandidateFromArray(const std::string& name, const CArray<double>& w) {
  GEODRIVE_CHECK_INPUT(w.ndim() == 2 && w.shape(1) == 4, "candidate ", name,
                       ": waypoints must be an (N, 4) array of t, x, y, yaw");
  Candidate c;
  c.name = name;
  c.source = "candidate " + name;
  for (py::ssize_t i = 0; i < w.shape(0); ++i) {
    const double* r = w.data() + 4 * i;
    c.ego0_from_ego.Add(r[0], EgoPose(r[1], r[2], 0.0, r[3]));
  }
  ValidateCandidate(c);
  return c;
}

void BindPlanning(py::module_& m) {
  m.def(
      "plan_json",
      [](const PyClip& clip, const std::vector<PathArg>& paths,
         const std::vector<std::string>& names,
         const std::vector<CArray<double>>& waypoints,
         const std::vector<double>& shifts, int sample, bool with_logged) {
        GEODRIVE_CHECK_INPUT(names.size() == waypoints.size(),
                             "plan: one name per waypoint array");
        GEODRIVE_CHECK_INPUT(sample >= 0 && sample <= 100000,
                             "plan: sample must be in [0, 100000]");
        std::vector<Candidate> extra;
        for (size_t i = 0; i < names.size(); ++i)
          extra.push_back(CandidateFromArray(names[i], waypoints[i]));
        py::gil_scoped_release release;
        GEODRIVE_CHECK_INPUT(!clip.clip.frames.empty(), "plan: empty clip");
        std::vector<Candidate> files;
        for (const PathArg& p : paths) {
          for (Candidate& c :
               ReadCandidates(p.value, clip.clip.frames.front().ego_from_cam))
            files.push_back(std::move(c));
        }
        for (Candidate& c : extra) files.push_back(std::move(c));
        const PlanningScene scene = PlanningSceneFromClip(clip.clip);
        const PlanScoreOptions options;
        const std::vector<Candidate> candidates = GatherCandidates(
            scene, with_logged, shifts, std::move(files), sample);
        const PlanResult result = ScoreCandidates(scene, candidates, options);
        return PlanResultToJson(clip.clip.id, candidates, result, options);
      },
      py::arg("clip"), py::arg("paths"), py::arg("names"), py::arg("waypoints"),
      py::arg("shifts"), py::arg("sample"), py::arg("with_logged"),
      "plan.json's text for a clip's candidates (geodrive.plan parses it).");
}

}  // namespace
}  // namespace geodrive

PYBIND11_MODULE(_core, m) {
  m.doc() = "geodrive: the GeoDrive toolkit's core over NumPy arrays";
  // Module-local: the translator applies to this module's functions only.
  py::register_local_exception_translator(geodrive::TranslateException);
  pthread_atfork(nullptr, nullptr, geodrive::ForkedChildRunsOpenMPSerially);
  geodrive::BindDataset(m);
  geodrive::BindClip(m);
  geodrive::BindScenes(m);
  geodrive::BindRender(m);
  geodrive::BindEditedRender(m);
  geodrive::BindTrajectories(m);
  geodrive::BindMetrics(m);
  geodrive::BindPlanning(m);
}
