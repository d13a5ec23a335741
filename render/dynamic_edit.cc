// Dynamic editing (dynamic_edit.h), shared parts: the edit modes and kinds,
// option checks, the summary and its JSON, per-instance box tracks, pixel
// boxes and the validation of the clip and the edits. The modes themselves are
// in dynamic_edit_2d.cc and dynamic_edit_3d.cc (with dynamic_edit_ground.cc and
// dynamic_edit_segment.cc), the CLI glue in dynamic_edit_cli.cc.

#include "render/dynamic_edit.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "geometry/util/status.h"
#include "render/internal/dynamic_edit_internal.h"

namespace geodrive {
namespace {

using json = nlohmann::json;

}  // namespace

namespace dynamic_edit_internal {

Track BuildTrack(const BoxSequence& seq, int num_frames, bool interpolate) {
  Track track;
  track.box_2d.resize(num_frames);
  track.box_3d.resize(num_frames);
  for (const BoxFrame& f : seq.frames) {
    if (f.frame < 0 || f.frame >= num_frames) continue;
    track.box_2d[f.frame] = f.box_2d;
    track.box_3d[f.frame] = f.box_3d;
  }
  if (!interpolate) return track;
  for (size_t k = 0; k + 1 < seq.frames.size(); ++k) {
    const BoxFrame& a = seq.frames[k];
    const BoxFrame& b = seq.frames[k + 1];
    if (b.frame - a.frame < 2 || b.frame > num_frames) continue;
    for (int f = a.frame + 1; f < b.frame; ++f) {
      const double t = double(f - a.frame) / (b.frame - a.frame);
      bool any = false;
      if (a.box_3d && b.box_3d) {
        track.box_3d[f] = Interpolate(*a.box_3d, *b.box_3d, t);
        any = true;
      }
      if (a.box_2d && b.box_2d) {
        track.box_2d[f] = Interpolate(*a.box_2d, *b.box_2d, t);
        any = true;
      }
      if (any) track.interpolated.push_back(f);
    }
  }
  return track;
}

// Pixel box of frame f in an image of width x height seen by `camera` (already
// at that size): the file's 2D box scaled, or the projected 3D box. `shift` is
// added to projected coordinates
// (-0.5 when the image uses kPixelCenter).
std::optional<Box2d> PixelBox(const Track& track,
                              int f,
                              const BoxSequences& boxes,
                              const PinholeCamera& camera,
                              const Rigid3d& cam_from_world,
                              double shift) {
  if (track.box_2d[f]) {
    return track.box_2d[f]->Scaled(double(camera.width) / boxes.image_width,
                                   double(camera.height) / boxes.image_height);
  }
  if (track.box_3d[f]) {
    std::optional<Box2d> b =
        ProjectBox3d(*track.box_3d[f], camera, cam_from_world);
    if (b) {
      b->xmin += shift;
      b->xmax += shift;
      b->ymin += shift;
      b->ymax += shift;
    }
    return b;
  }
  return std::nullopt;
}

// Integer pixel window of a box, as upstream: [floor(xmin), floor(xmax)) x
// [floor(ymin), floor(ymax)) clamped to the image.
cv::Rect PixelWindow(const Box2d& b, int width, int height) {
  const int x0 = std::clamp(static_cast<int>(std::floor(b.xmin)), 0, width);
  const int y0 = std::clamp(static_cast<int>(std::floor(b.ymin)), 0, height);
  const int x1 = std::clamp(static_cast<int>(std::floor(b.xmax)), 0, width);
  const int y1 = std::clamp(static_cast<int>(std::floor(b.ymax)), 0, height);
  return cv::Rect(x0, y0, std::max(0, x1 - x0), std::max(0, y1 - y0));
}

void AddNote(DynamicEditSummary* summary,
             const std::string& instance,
             int frame,
             const std::string& message) {
  summary->notes.push_back(EditNote{instance, frame, message});
}

std::string FrameList(const std::vector<int>& frames) {
  std::ostringstream os;
  for (size_t i = 0; i < frames.size(); ++i) os << (i ? "," : "") << frames[i];
  return os.str();
}

EditPlan PlanEdits(const BoxSequences& boxes,
                   const std::vector<ObjectEdit>& edits) {
  EditPlan plan;
  std::set<std::string> ids;
  for (const BoxSequence& s : boxes.instances) ids.insert(s.id);
  for (const ObjectEdit& e : edits) {
    const std::string what = ToString(e.kind) + " '" + e.instance + "'";
    GEODRIVE_CHECK_INPUT(boxes.Find(e.instance) != nullptr, "edit ", what,
                         ": no instance with this id in the boxes file");
    switch (e.kind) {
      case ObjectEditKind::kRemove:
        GEODRIVE_CHECK_INPUT(!plan.moved.count(e.instance) &&
                                 plan.removed.insert(e.instance).second,
                             "edit ", what,
                             ": the instance is already removed or moved");
        break;
      case ObjectEditKind::kMove:
        GEODRIVE_CHECK_INPUT(
            !plan.removed.count(e.instance) && !plan.moved.count(e.instance),
            "edit ", what, ": the instance is already removed or moved");
        plan.moved[e.instance] = &e.sequence;
        break;
      case ObjectEditKind::kInsert:
        GEODRIVE_CHECK_INPUT(
            !e.sequence.id.empty(), "edit ", what,
            ": the inserted copy needs an id (its box sequence's id)");
        GEODRIVE_CHECK_INPUT(ids.insert(e.sequence.id).second, "edit ", what,
                             ": id '", e.sequence.id,
                             "' of the copy is already used");
        plan.inserts.push_back(&e);
        break;
    }
    if (e.kind != ObjectEditKind::kRemove) {
      BoxSequences one;
      one.image_width = boxes.image_width;
      one.image_height = boxes.image_height;
      one.num_frames = boxes.num_frames;
      one.instances.push_back(e.sequence);
      if (one.instances[0].id.empty()) one.instances[0].id = e.instance;
      one.Check("edit " + what);
    }
  }
  return plan;
}

void CheckClip(const std::vector<PinholeCamera>& cameras,
               const std::vector<Rigid3d>& cam_from_world,
               const BoxSequences& boxes) {
  GEODRIVE_CHECK_INPUT(!cam_from_world.empty(),
                       "dynamic edit: no camera poses given");
  GEODRIVE_CHECK_INPUT(
      cameras.size() == 1 || cameras.size() == cam_from_world.size(),
      "dynamic edit: ", cameras.size(), " cameras for ", cam_from_world.size(),
      " poses (need 1 or one per pose)");
  GEODRIVE_CHECK_INPUT(
      boxes.num_frames == static_cast<int>(cam_from_world.size()),
      "dynamic edit: the boxes file has num_frames ", boxes.num_frames,
      " but the clip has ", cam_from_world.size(), " frames");
  for (size_t f = 0; f < cam_from_world.size(); ++f) {
    CheckPose(cam_from_world[f], "dynamic edit: frame " + std::to_string(f));
  }
  for (const PinholeCamera& c : cameras) c.Check("dynamic edit: camera");
  boxes.Check("dynamic edit: boxes");
}

// Keeps only positions, colours and instance ids (all -1).
PointCloud StripForRender(const PointCloud& cloud,
                          const std::vector<size_t>& keep) {
  PointCloud out;
  out.positions.reserve(keep.size());
  for (size_t i : keep) out.positions.push_back(cloud.positions[i]);
  if (cloud.HasColors()) {
    out.colors.reserve(keep.size());
    for (size_t i : keep) out.colors.push_back(cloud.colors[i]);
  }
  // Capture footprints travel with their points (footprint splats).
  for (size_t i : keep) {
    if (cloud.HasFootprints()) out.footprints.push_back(cloud.footprints[i]);
    if (!cloud.footprint_u.empty()) {
      out.footprint_u.push_back(cloud.footprint_u[i]);
      out.footprint_v.push_back(cloud.footprint_v[i]);
    }
  }
  out.instance_ids.assign(keep.size(), -1);
  return out;
}

}  // namespace dynamic_edit_internal

std::string ToString(EditMode mode) {
  return mode == EditMode::k2d ? "2d" : "3d";
}

EditMode ParseEditMode(const std::string& text) {
  if (text == "2d") return EditMode::k2d;
  if (text == "3d") return EditMode::k3d;
  ThrowInputError("edit mode", "'", text, "' is not one of 2d, 3d");
}

std::string ToString(ObjectEditKind kind) {
  switch (kind) {
    case ObjectEditKind::kRemove:
      return "remove";
    case ObjectEditKind::kInsert:
      return "insert";
    case ObjectEditKind::kMove:
      return "move";
  }
  return "?";
}

void DynamicEditOptions::Check() const {
  GEODRIVE_CHECK_INPUT(std::isfinite(min_box_area_px) && min_box_area_px >= 0,
                       "dynamic edit options: min_box_area_px must be >= 0");
  GEODRIVE_CHECK_INPUT(
      frame0_image.empty() || frame0_image.type() == CV_8UC3,
      "dynamic edit options: frame0_image must be RGB CV_8UC3");
  GEODRIVE_CHECK_INPUT(std::isfinite(box_margin) && box_margin >= 0,
                       "dynamic edit options: box_margin must be >= 0");
  GEODRIVE_CHECK_INPUT(std::isfinite(ground_margin) && ground_margin > 0,
                       "dynamic edit options: ground_margin must be > 0");
  if (ground_plane) {
    GEODRIVE_CHECK_INPUT(
        ground_plane->allFinite() &&
            std::abs(ground_plane->head<3>().norm() - 1.0) < 1e-6,
        "dynamic edit options: ground_plane needs a finite unit normal");
  }
  GEODRIVE_CHECK_INPUT(
      ground_max_tilt_deg > 0 && ground_max_tilt_deg < 90,
      "dynamic edit options: ground_max_tilt_deg must be in (0, 90)");
  GEODRIVE_CHECK_INPUT(
      ground_ransac_iterations >= 1 && ground_ransac_samples >= 3,
      "dynamic edit options: need ground_ransac_iterations >= 1 and "
      "ground_ransac_samples >= 3");
  GEODRIVE_CHECK_INPUT(
      ground_ransac_confidence > 0 && ground_ransac_confidence < 1,
      "dynamic edit options: ground_ransac_confidence must be in (0, 1)");
  GEODRIVE_CHECK_INPUT(dynamic_mask.empty() || dynamic_mask.type() == CV_8U,
                       "dynamic edit options: dynamic_mask must be CV_8U");
  GEODRIVE_CHECK_INPUT(std::isfinite(depth_gap_abs) && depth_gap_abs >= 0 &&
                           std::isfinite(depth_gap_rel) && depth_gap_rel >= 0,
                       "dynamic edit options: depth gaps must be >= 0");
  GEODRIVE_CHECK_INPUT(min_object_points >= 1,
                       "dynamic edit options: min_object_points must be >= 1");
  GEODRIVE_CHECK_INPUT(
      std::isfinite(max_magnification) && max_magnification >= 1 &&
          max_magnification <= 16,
      "dynamic edit options: max_magnification must be in [1, 16]");
  GEODRIVE_CHECK_INPUT(num_threads >= 0,
                       "dynamic edit options: num_threads must be >= 0");
}

std::string DynamicEditSummary::BriefReport() const {
  std::ostringstream os;
  os << "dynamic edit (" << ToString(mode) << "): " << num_objects
     << " object(s) over " << num_frames << " frames";
  if (mode == EditMode::k3d) os << ", " << object_points << " moving points";
  os << ", " << removed_points << " points removed;";
  for (const AppliedEdit& e : edits) {
    os << " " << e.kind << " " << e.instance;
    if (!e.source.empty()) os << "<-" << e.source;
    os << " (" << e.num_points << " pts, " << e.frames_shown << " frames);";
  }
  if (!notes.empty()) os << " " << notes.size() << " note(s)";
  os << "; " << seconds << " s";
  return os.str();
}

std::string DynamicEditSummary::ToJson() const {
  json j;
  j["mode"] = ToString(mode);
  j["num_frames"] = num_frames;
  j["num_objects"] = num_objects;
  j["object_points"] = object_points;
  j["removed_points"] = removed_points;
  if (ground_plane) {
    j["ground_plane"] = {(*ground_plane)[0], (*ground_plane)[1],
                         (*ground_plane)[2], (*ground_plane)[3]};
    j["ground_plane_estimated"] = ground_plane_estimated;
  }
  json jedits = json::array();
  for (const AppliedEdit& e : edits) {
    json je = {{"kind", e.kind},
               {"instance", e.instance},
               {"num_points", e.num_points},
               {"frames_shown", e.frames_shown}};
    if (!e.source.empty()) je["source"] = e.source;
    jedits.push_back(je);
  }
  j["edits"] = jedits;
  json jnotes = json::array();
  for (const EditNote& n : notes) {
    json jn = {{"instance", n.instance}, {"message", n.message}};
    if (n.frame >= 0) jn["frame"] = n.frame;
    jnotes.push_back(jn);
  }
  j["notes"] = jnotes;
  j["seconds"] = seconds;
  return j.dump();
}

RenderResult DynamicEditResult::ToRenderResult() && {
  RenderResult r;
  r.frames = std::move(frames);
  r.summary = render_summary;
  return r;
}

}  // namespace geodrive
