#include "dataset/pairs.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "geometry/util/files.h"
#include "geometry/util/input_file.h"
#include "geometry/util/json_fields.h"
#include "geometry/util/names.h"
#include "geometry/util/status.h"

namespace geodrive {

using nlohmann::json;

namespace {

json PoseToJson(const Rigid3d& pose) {
  const Eigen::Matrix4d m = pose.ToMatrix();
  json rows = json::array();
  for (int r = 0; r < 4; ++r)
    rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

Rigid3d PoseFromJson(const json& j, const std::string& what) {
  GEODRIVE_CHECK_INPUT(j.is_array() && j.size() == 4, what,
                       ": world_from_cam entry is not 4x4");
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    GEODRIVE_CHECK_INPUT(j[r].is_array() && j[r].size() == 4, what,
                         ": world_from_cam entry is not 4x4");
    for (int c = 0; c < 4; ++c) m(r, c) = j[r][c].get<double>();
  }
  return Rigid3d::FromMatrix(m, 1e-5);
}

// A whole regular file (ReadFileText: size-capped, a device or a pipe is an
// error, not an endless read).
std::string ReadText(const std::string& path) {
  return ReadFileText(path, uint64_t{1} << 30);
}

json IntrinsicsToJson(const PinholeCamera& c) {
  return {{"fx", c.fx}, {"fy", c.fy},       {"cx", c.cx},
          {"cy", c.cy}, {"width", c.width}, {"height", c.height}};
}

json PsnrToJson(const std::vector<std::optional<double>>& psnr) {
  json a = json::array();
  for (const auto& p : psnr) a.push_back(p ? json(*p) : json(nullptr));
  return a;
}

json FramesToJson(const std::vector<PairFrame>& frames) {
  json a = json::array();
  for (const auto& f : frames)
    a.push_back({{"sample_data_token", f.sample_data_token},
                 {"timestamp_us", f.timestamp_us},
                 {"filename", f.filename}});
  return a;
}

json PairViewToJson(const PairView& v) {
  json j;
  j["channel"] = v.channel;
  j["frames"] = FramesToJson(v.frames);
  j["intrinsics"] = IntrinsicsToJson(v.intrinsics);
  j["intrinsics"]["pixel_convention"] = "integer-index";
  json poses = json::array();
  for (const auto& p : v.world_from_cam) poses.push_back(PoseToJson(p));
  j["world_from_cam"] = poses;
  j["coverage"] = v.coverage;
  j["psnr_static"] = PsnrToJson(v.psnr_static);
  if (v.supported_fraction) j["supported_fraction"] = *v.supported_fraction;
  if (v.coverage_of_supported)
    j["coverage_of_supported"] = *v.coverage_of_supported;
  j["points_built"] = v.points_built;
  j["points_kept"] = v.points_kept;
  j["files"] = v.files;
  return j;
}

}  // namespace

std::string PairMetaToJson(const PairMeta& m) {
  json j;
  j["schema"] = "geodrive.pair_meta/1";
  j["clip_id"] = m.clip_id;
  j["scene"] = {{"name", m.scene_name}, {"token", m.scene_token}};
  json frames = json::array();
  for (const auto& f : m.frames) {
    frames.push_back({{"sample_data_token", f.sample_data_token},
                      {"timestamp_us", f.timestamp_us},
                      {"filename", f.filename}});
  }
  j["frames"] = frames;
  j["num_frames"] = m.frames.size();
  j["frame_source"] = m.frame_source;
  if (m.frame_interval_s > 0) j["frame_interval_s"] = m.frame_interval_s;
  if (m.upstream_scene_idx) j["upstream_scene_idx"] = *m.upstream_scene_idx;
  if (m.novel_view) {
    j["novel_view"] = {{"source_clip_id", m.novel_view->source_clip_id},
                       {"lateral_offset_m", m.novel_view->lateral_offset_m}};
  }
  j["fps"] = m.fps;
  j["intrinsics"] = {{"fx", m.intrinsics.fx},
                     {"fy", m.intrinsics.fy},
                     {"cx", m.intrinsics.cx},
                     {"cy", m.intrinsics.cy},
                     {"width", m.intrinsics.width},
                     {"height", m.intrinsics.height},
                     {"pixel_convention", "integer-index"}};
  j["resize_mode"] = m.resize_mode;
  json poses = json::array();
  for (const auto& p : m.world_from_cam) poses.push_back(PoseToJson(p));
  j["world_from_cam"] = poses;
  j["pose_units"] = m.pose_units;
  j["scale"] = {{"value", m.scale},
                {"source", m.scale_source},
                {"report", m.scale_report}};
  j["geometry_source"] = m.geometry_source;
  j["preset"] = m.preset;
  j["edit_mode"] = m.edit_mode;
  j["options"] =
      m.options_json.empty() ? json::object() : json::parse(m.options_json);
  j["options_hash"] = m.options_hash;
  j["tool_version"] = m.tool_version;
  json q;
  q["coverage"] = m.quality.coverage;
  if (m.quality.reprojection_rms_px_before)
    q["reprojection_rms_px_before"] = *m.quality.reprojection_rms_px_before;
  if (m.quality.reprojection_rms_px_after)
    q["reprojection_rms_px_after"] = *m.quality.reprojection_rms_px_after;
  if (m.quality.supported_fraction)
    q["supported_fraction"] = *m.quality.supported_fraction;
  if (m.quality.coverage_of_supported)
    q["coverage_of_supported"] = *m.quality.coverage_of_supported;
  if (const auto& h = m.quality.completion_holdout) {
    q["completion_holdout"] = {{"held_out", h->held_out},
                               {"covered", h->covered},
                               {"mae_m", h->mae_m},
                               {"rmse_m", h->rmse_m},
                               {"within_5_percent", h->within_5_percent},
                               {"within_10_percent", h->within_10_percent}};
  }
  if (m.quality.scale_inlier_fraction)
    q["scale_inlier_fraction"] = *m.quality.scale_inlier_fraction;
  json psnr = json::array();
  for (const auto& p : m.quality.psnr_static)
    psnr.push_back(p ? json(*p) : json(nullptr));
  q["psnr_static"] = psnr;
  j["quality"] = q;
  j["files"] = m.files;
  if (!m.file_sizes.empty()) j["file_sizes"] = m.file_sizes;
  if (!m.views.empty()) {
    json views = json::array();
    for (const PairView& v : m.views) views.push_back(PairViewToJson(v));
    j["views"] = views;
    json seams = json::array();
    for (const PairSeam& s : m.seams)
      seams.push_back({{"camera_a", s.camera_a},
                       {"camera_b", s.camera_b},
                       {"overlap_pixels", s.overlap_pixels},
                       {"agreeing_fraction", s.agreeing_fraction}});
    j["seams"] = seams;
  }
  return j.dump(2) + "\n";
}

namespace {

// A number field that may be absent or null (older metas wrote -1 for "not
// computed": read as absent).
std::optional<double> OptionalNumber(const json& j, const char* key) {
  if (!j.contains(key) || j.at(key).is_null()) return std::nullopt;
  const double v = j.at(key).get<double>();
  if (v < 0) return std::nullopt;
  return v;
}

std::vector<PairFrame> FramesFromJson(const json& a, const std::string& what) {
  std::vector<PairFrame> frames;
  for (const auto& f : a) {
    frames.push_back({f.at("sample_data_token").get<std::string>(),
                      internal::JsonInt(what, f.at("timestamp_us"),
                                        "frames[].timestamp_us", 0, INT64_MAX),
                      f.at("filename").get<std::string>()});
  }
  return frames;
}

PinholeCamera IntrinsicsFromJson(const json& k, const std::string& what) {
  return PinholeCamera(
      k.at("fx").get<double>(), k.at("fy").get<double>(),
      k.at("cx").get<double>(), k.at("cy").get<double>(),
      static_cast<int>(internal::JsonInt(
          what, k.at("width"), "intrinsics.width", 1, internal::kMaxImageSide)),
      static_cast<int>(internal::JsonInt(what, k.at("height"),
                                         "intrinsics.height", 1,
                                         internal::kMaxImageSide)));
}

std::vector<std::optional<double>> PsnrFromJson(const json& a) {
  std::vector<std::optional<double>> out;
  for (const auto& p : a)
    out.push_back(p.is_null() ? std::nullopt
                              : std::optional<double>(p.get<double>()));
  return out;
}

PairView PairViewFromJson(const json& j, const std::string& what) {
  PairView v;
  v.channel = j.at("channel").get<std::string>();
  const std::string where = what + ": views[" + v.channel + "]";
  v.frames = FramesFromJson(j.at("frames"), where);
  v.intrinsics = IntrinsicsFromJson(j.at("intrinsics"), where);
  for (const auto& p : j.at("world_from_cam"))
    v.world_from_cam.push_back(PoseFromJson(p, where));
  v.coverage = j.at("coverage").get<std::vector<double>>();
  v.psnr_static = PsnrFromJson(j.at("psnr_static"));
  v.supported_fraction = OptionalNumber(j, "supported_fraction");
  v.coverage_of_supported = OptionalNumber(j, "coverage_of_supported");
  v.points_built = internal::JsonInt(where, j.at("points_built"),
                                     "points_built", 0, INT64_MAX);
  v.points_kept = internal::JsonInt(where, j.at("points_kept"), "points_kept",
                                    0, INT64_MAX);
  v.files = j.at("files").get<std::map<std::string, std::string>>();
  GEODRIVE_CHECK_INPUT(v.world_from_cam.size() == v.frames.size() &&
                           v.coverage.size() == v.frames.size(),
                       where, ": ", v.frames.size(), " frames, ",
                       v.world_from_cam.size(), " poses, ", v.coverage.size(),
                       " coverages");
  return v;
}

}  // namespace

PairMeta PairMetaFromJson(const std::string& text, const std::string& what) {
  json j;
  try {
    j = internal::ParseJson(text, what);
  } catch (const json::exception& e) {
    ThrowInputError(what, "malformed JSON (", e.what(), ")");
  }
  PairMeta m;
  try {
    m.clip_id = j.at("clip_id").get<std::string>();
    m.scene_name = j.at("scene").at("name").get<std::string>();
    m.scene_token = j.at("scene").at("token").get<std::string>();
    for (const auto& f : j.at("frames")) {
      m.frames.push_back(
          {f.at("sample_data_token").get<std::string>(),
           internal::JsonInt(what, f.at("timestamp_us"),
                             "frames[].timestamp_us", 0, INT64_MAX),
           f.at("filename").get<std::string>()});
    }
    m.fps = j.at("fps").get<double>();
    const auto& k = j.at("intrinsics");
    m.intrinsics = PinholeCamera(
        k.at("fx").get<double>(), k.at("fy").get<double>(),
        k.at("cx").get<double>(), k.at("cy").get<double>(),
        static_cast<int>(internal::JsonInt(what, k.at("width"),
                                           "intrinsics.width", 1,
                                           internal::kMaxImageSide)),
        static_cast<int>(internal::JsonInt(what, k.at("height"),
                                           "intrinsics.height", 1,
                                           internal::kMaxImageSide)));
    m.resize_mode = j.at("resize_mode").get<std::string>();
    for (const auto& p : j.at("world_from_cam"))
      m.world_from_cam.push_back(PoseFromJson(p, what));
    m.pose_units = j.at("pose_units").get<std::string>();
    m.scale = j.at("scale").at("value").get<double>();
    m.scale_source = j.at("scale").at("source").get<std::string>();
    m.scale_report = j.at("scale").value("report", "");
    m.geometry_source = j.at("geometry_source").get<std::string>();
    m.preset = j.value("preset", "");
    m.edit_mode = j.value("edit_mode", "");
    m.options_json = j.at("options").dump();
    m.options_hash = j.at("options_hash").get<std::string>();
    m.tool_version = j.at("tool_version").get<std::string>();
    const auto& q = j.at("quality");
    m.quality.coverage = q.at("coverage").get<std::vector<double>>();
    m.quality.reprojection_rms_px_before =
        OptionalNumber(q, "reprojection_rms_px_before");
    m.quality.reprojection_rms_px_after =
        OptionalNumber(q, "reprojection_rms_px_after");
    m.quality.supported_fraction = OptionalNumber(q, "supported_fraction");
    m.quality.coverage_of_supported =
        OptionalNumber(q, "coverage_of_supported");
    if (q.contains("completion_holdout")) {
      const auto& h = q.at("completion_holdout");
      PairQuality::HoldOut v;
      v.held_out = internal::JsonInt(what, h.at("held_out"),
                                     "quality.completion_holdout.held_out", 0,
                                     INT64_MAX);
      v.covered =
          internal::JsonInt(what, h.at("covered"),
                            "quality.completion_holdout.covered", 0, INT64_MAX);
      v.mae_m = h.at("mae_m").get<double>();
      v.rmse_m = h.at("rmse_m").get<double>();
      v.within_5_percent = h.at("within_5_percent").get<double>();
      v.within_10_percent = h.at("within_10_percent").get<double>();
      m.quality.completion_holdout = v;
    }
    m.quality.scale_inlier_fraction =
        OptionalNumber(q, "scale_inlier_fraction");
    if (q.contains("psnr_static")) {
      for (const auto& p : q.at("psnr_static")) {
        m.quality.psnr_static.push_back(
            p.is_null() ? std::nullopt
                        : std::optional<double>(p.get<double>()));
      }
    }
    m.frame_source = j.value("frame_source", std::string("all"));
    m.frame_interval_s = j.value("frame_interval_s", 0.0);
    if (j.contains("upstream_scene_idx"))
      m.upstream_scene_idx = static_cast<int>(
          internal::JsonInt(what, j.at("upstream_scene_idx"),
                            "upstream_scene_idx", 0, INT32_MAX));
    if (j.contains("novel_view")) {
      const json& nv = j.at("novel_view");
      PairNovelView v;
      v.source_clip_id = nv.at("source_clip_id").get<std::string>();
      v.lateral_offset_m = nv.at("lateral_offset_m").get<double>();
      GEODRIVE_CHECK_INPUT(std::isfinite(v.lateral_offset_m), what,
                           ": novel_view.lateral_offset_m is not finite");
      m.novel_view = v;
    }
    m.files = j.at("files").get<std::map<std::string, std::string>>();
    if (j.contains("file_sizes"))
      m.file_sizes = j.at("file_sizes").get<std::map<std::string, uint64_t>>();
    if (j.contains("views")) {
      for (const auto& v : j.at("views"))
        m.views.push_back(PairViewFromJson(v, what));
      for (const auto& sj : j.at("seams")) {
        PairSeam seam;
        seam.camera_a = sj.at("camera_a").get<std::string>();
        seam.camera_b = sj.at("camera_b").get<std::string>();
        seam.overlap_pixels =
            internal::JsonInt(what, sj.at("overlap_pixels"),
                              "seams[].overlap_pixels", 0, INT64_MAX);
        seam.agreeing_fraction = sj.at("agreeing_fraction").get<double>();
        m.seams.push_back(seam);
      }
    }
  } catch (const json::exception& e) {
    ThrowInputError(what, "missing or mistyped field (", e.what(), ")");
  }
  GEODRIVE_CHECK_INPUT(m.world_from_cam.size() == m.frames.size(), what, ": ",
                       m.frames.size(), " frames but ", m.world_from_cam.size(),
                       " poses");
  for (const PairView& v : m.views)
    GEODRIVE_CHECK_INPUT(v.frames.size() == m.frames.size(), what, ": view ",
                         v.channel, " has ", v.frames.size(), " frames, the ",
                         "pair ", m.frames.size());
  return m;
}

PairMeta ReadPairMeta(const std::string& pair_dir) {
  const std::string path = pair_dir + "/meta.json";
  return PairMetaFromJson(ReadText(path), path);
}

PairRecord ReadPair(const std::string& build_dir, const ManifestEntry& entry) {
  const std::string& rel = entry.pair_dir;
  const std::string where = build_dir + "/manifest.jsonl";
  CheckRelativePathInside(rel,
                          where + ": pair '" + entry.clip_id + "' pair_dir");
  PairRecord r;
  r.entry = entry;
  r.dir = build_dir + "/" + rel;
  r.meta = ReadPairMeta(r.dir);
  const std::string meta_path = r.dir + "/meta.json";
  GEODRIVE_CHECK_INPUT(r.meta.clip_id == entry.clip_id, meta_path,
                       ": clip_id '", r.meta.clip_id,
                       "' differs from the manifest's '", entry.clip_id, "'");
  auto resolve = [&](const char* lossless, const char* video) {
    for (const char* role : {lossless, video}) {
      const auto it = r.meta.files.find(role);
      if (it == r.meta.files.end()) continue;
      const std::string& name = it->second;
      GEODRIVE_CHECK_INPUT(!name.empty() &&
                               name.find('/') == std::string::npos &&
                               name != "." && name != "..",
                           meta_path, ": files.", role, " = '", name,
                           "' is not a plain name inside the pair folder");
      const std::string path = r.dir + "/" + name;
      // A frame folder, or a regular file (CheckInputFile: a FIFO or a
      // device is refused, never opened).
      std::error_code ec;
      if (!std::filesystem::is_directory(path, ec)) {
        GEODRIVE_CHECK_INPUT(std::filesystem::exists(path, ec), path,
                             ": missing (listed in meta.json files.", role,
                             ")");
        CheckInputFile(path);
      }
      return path;
    }
    ThrowInputError(meta_path, "files has neither '", lossless, "' nor '",
                    video, "'");
  };
  r.gt_video = resolve("gt_frames", "gt");
  r.cond_video = resolve("cond_frames", "cond");
  std::vector<std::string> channels;
  for (const PairView& v : r.meta.views) channels.push_back(v.channel);
  GEODRIVE_CHECK_INPUT(entry.cameras.empty() || entry.cameras == channels,
                       where, ": pair '", entry.clip_id,
                       "' lists other cameras than its meta.json views");
  for (const PairView& v : r.meta.views) {
    for (const char* role : {"gt", "cond"}) {
      const auto it = v.files.find(role);
      GEODRIVE_CHECK_INPUT(it != v.files.end(), meta_path, ": view ", v.channel,
                           " has no files.", role);
      const std::string& name = it->second;
      GEODRIVE_CHECK_INPUT(IsPlainPathComponent(name), meta_path, ": view ",
                           v.channel, " files.", role, " = '", name,
                           "' is not a plain name inside the pair folder");
      const std::string path = r.dir + "/" + name;
      CheckInputFile(path);
      (role[0] == 'g' ? r.view_gt_videos : r.view_cond_videos).push_back(path);
    }
  }
  return r;
}

std::string ManifestEntryToJson(const ManifestEntry& e) {
  json j = {{"clip_id", e.clip_id},
            {"pair_dir", e.pair_dir},
            {"scene", e.scene_name},
            {"num_frames", e.num_frames},
            {"geometry_source", e.geometry_source},
            {"pose_units", e.pose_units},
            {"mean_coverage", e.mean_coverage},
            {"options_hash", e.options_hash}};
  if (!e.cameras.empty()) j["cameras"] = e.cameras;
  return j.dump();
}

ManifestEntry ManifestEntryFromJson(const std::string& line,
                                    const std::string& what) {
  ManifestEntry e;
  try {
    const json j = internal::ParseJson(line, what);
    e.clip_id = j.at("clip_id").get<std::string>();
    e.pair_dir = j.at("pair_dir").get<std::string>();
    e.scene_name = j.at("scene").get<std::string>();
    e.num_frames = static_cast<int>(
        internal::JsonInt(what, j.at("num_frames"), "num_frames", 1, 1 << 20));
    e.geometry_source = j.at("geometry_source").get<std::string>();
    e.pose_units = j.at("pose_units").get<std::string>();
    e.mean_coverage = j.at("mean_coverage").get<double>();
    e.options_hash = j.at("options_hash").get<std::string>();
    if (j.contains("cameras"))
      e.cameras = j.at("cameras").get<std::vector<std::string>>();
  } catch (const json::exception& ex) {
    ThrowInputError(what, "bad manifest line (", ex.what(), ")");
  }
  // Both name folders and files of every reader (PairDataset, generate,
  // eval): a plain clip id, a pair_dir inside the build folder.
  GEODRIVE_CHECK_INPUT(IsPlainPathComponent(e.clip_id), what, ": clip_id '",
                       PathComponentFromName(e.clip_id, what),
                       "' (percent-encoded) is not a plain folder name");
  CheckRelativePathInside(e.pair_dir, what + ": pair_dir");
  return e;
}

std::vector<ManifestEntry> ReadManifest(const std::string& path) {
  std::istringstream in(ReadText(path));
  std::vector<ManifestEntry> out;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty()) continue;
    out.push_back(ManifestEntryFromJson(line, path + ":" + std::to_string(n)));
  }
  return out;
}

std::string FailureEntryToJson(const FailureEntry& e) {
  return json({{"clip_id", e.clip_id}, {"stage", e.stage}, {"error", e.error}})
      .dump();
}

std::vector<FailureEntry> ReadFailures(const std::string& path) {
  std::istringstream in(ReadText(path));
  std::vector<FailureEntry> out;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty()) continue;
    try {
      const json j = internal::ParseJson(line, path + ":" + std::to_string(n));
      out.push_back({j.at("clip_id").get<std::string>(),
                     j.at("stage").get<std::string>(),
                     j.at("error").get<std::string>()});
    } catch (const json::exception& e) {
      ThrowInputError(path + ":" + std::to_string(n), "bad failure line (",
                      e.what(), ")");
    }
  }
  return out;
}

}  // namespace geodrive
