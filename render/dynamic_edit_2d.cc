// Dynamic editing, 2D mode (upstream GeoDrive `prepare_data_edit.py`): delete
// the points of each instance's frame-0 box, render the static scene, then
// paste the feathered frame-0 crop of each instance into its box in every
// frame.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "geometry/util/status.h"
#include "render/dynamic_edit.h"
#include "render/internal/dynamic_edit_internal.h"

namespace geodrive {
namespace {

using dynamic_edit_internal::AddNote;
using dynamic_edit_internal::BuildTrack;
using dynamic_edit_internal::CameraOf;
using dynamic_edit_internal::EditPlan;
using dynamic_edit_internal::Frame0Projection;
using dynamic_edit_internal::FrameList;
using dynamic_edit_internal::InWindow;
using dynamic_edit_internal::PixelBox;
using dynamic_edit_internal::PixelWindow;
using dynamic_edit_internal::PlanEdits;
using dynamic_edit_internal::ProjectFrame0;
using dynamic_edit_internal::StripForRender;
using dynamic_edit_internal::Track;

RenderedFrame EmptyFrame(const RenderOptions& options) {
  RenderedFrame frame;
  frame.rgb = cv::Mat::zeros(options.height, options.width, CV_8UC3);
  frame.depth = cv::Mat::zeros(options.height, options.width, CV_32F);
  frame.mask = cv::Mat::zeros(options.height, options.width, CV_8U);
  if (options.output_index)
    frame.index = cv::Mat(options.height, options.width, CV_32S, -1);
  frame.instance = cv::Mat(options.height, options.width, CV_32S, -1);
  if (options.output_float_rgb)
    frame.rgb_float = cv::Mat::zeros(options.height, options.width, CV_32FC3);
  return frame;
}

void CopyFrameRest(RenderedFrame* frame, const RenderOptions& options) {
  if (frame->instance.empty())
    frame->instance = cv::Mat(options.height, options.width, CV_32S, -1);
}

// 1. Delete the points in each instance's frame-0 box region (camera 0, its
// own pixel grid): returns the rest, the static background.
PointCloud RemoveFrame0BoxPoints(const PointCloud& cloud_in_world,
                                 const PinholeCamera& camera0,
                                 const Rigid3d& cam_from_world0,
                                 const BoxSequences& boxes,
                                 const std::vector<Track>& tracks,
                                 DynamicEditSummary* summary) {
  const Frame0Projection proj =
      ProjectFrame0(cloud_in_world, camera0, cam_from_world0);
  std::vector<cv::Rect> windows;
  for (size_t k = 0; k < boxes.instances.size(); ++k) {
    const std::optional<Box2d> b =
        PixelBox(tracks[k], 0, boxes, camera0, cam_from_world0);
    if (!b) {
      AddNote(summary, boxes.instances[k].id, 0,
              "no box in frame 0: nothing removed or pasted for it");
      continue;
    }
    const cv::Rect w = PixelWindow(*b, camera0.width, camera0.height);
    if (w.area() == 0) {
      AddNote(summary, boxes.instances[k].id, 0,
              "frame-0 box is empty or outside the image: nothing removed or "
              "pasted for it");
      continue;
    }
    windows.push_back(w);
  }
  std::vector<size_t> keep;
  keep.reserve(cloud_in_world.size());
  for (size_t i = 0; i < cloud_in_world.size(); ++i) {
    bool inside = false;
    if (proj.u[i] >= 0) {
      for (const cv::Rect& w : windows)
        inside = inside || InWindow(w, proj.u[i], proj.v[i]);
    }
    if (!inside) keep.push_back(i);
  }
  summary->removed_points =
      static_cast<int64_t>(cloud_in_world.size() - keep.size());
  return StripForRender(cloud_in_world, keep);
}

// 2. Static render of the background (`render_options` asks for the instance
// map: it marks pasted pixels).
std::vector<RenderedFrame> RenderBackground(
    const PointCloud& background,
    const std::vector<PinholeCamera>& cameras,
    const std::vector<Rigid3d>& cam_from_world,
    const RenderOptions& render_options) {
  const int num_frames = static_cast<int>(cam_from_world.size());
  std::vector<RenderedFrame> frames;
  if (background.empty()) {
    frames.assign(num_frames, RenderedFrame());
    for (int f = 0; f < num_frames; ++f) frames[f] = EmptyFrame(render_options);
  } else {
    frames = RenderFrames(background, cameras, cam_from_world, render_options)
                 .frames;
  }
  for (RenderedFrame& f : frames) CopyFrameRest(&f, render_options);
  return frames;
}

// 3. The crop source: options.frame0_image at the render size, or the
// unedited frame-0 render.
cv::Mat CropSource(const PointCloud& cloud_in_world,
                   const std::vector<PinholeCamera>& cameras,
                   const std::vector<Rigid3d>& cam_from_world,
                   const DynamicEditOptions& options,
                   const RenderOptions& render_options) {
  const int W = render_options.width, H = render_options.height;
  cv::Mat source;
  if (!options.frame0_image.empty()) {
    cv::resize(options.frame0_image, source, cv::Size(W, H), 0, 0,
               cv::INTER_LINEAR);
  } else {
    RenderOptions o = render_options;
    o.output_instance = false;
    o.output_index = false;
    source = RenderFrame(cloud_in_world, cameras[0], cam_from_world[0], o).rgb;
  }
  return source;
}

// One instance (or inserted copy) to paste: the frame-0 crop of
// `source_track` along `track`.
struct Paste {
  std::string id, source_id, kind;
  const Track* source_track;
  Track track;
};

// 4. The pastes, instances in order, then inserted copies; removed instances
// are listed as applied edits.
std::vector<Paste> PlanPastes(const BoxSequences& boxes,
                              const std::vector<Track>& tracks,
                              const EditPlan& plan,
                              const DynamicEditOptions& options,
                              int num_frames,
                              DynamicEditSummary* summary) {
  std::vector<Paste> pastes;
  for (size_t k = 0; k < boxes.instances.size(); ++k) {
    const std::string& id = boxes.instances[k].id;
    if (plan.removed.count(id)) {
      summary->edits.push_back(AppliedEdit{"remove", id, "", 0, 0});
      continue;
    }
    const auto moved = plan.moved.find(id);
    if (moved != plan.moved.end()) {
      pastes.push_back(Paste{
          id, id, "move", &tracks[k],
          BuildTrack(*moved->second, num_frames, options.interpolate_missing)});
    } else {
      pastes.push_back(Paste{id, id, "animate", &tracks[k], tracks[k]});
    }
  }
  for (const ObjectEdit* e : plan.inserts) {
    size_t k = 0;
    while (boxes.instances[k].id != e->instance) ++k;
    pastes.push_back(Paste{
        e->sequence.id, e->instance, "insert", &tracks[k],
        BuildTrack(e->sequence, num_frames, options.interpolate_missing)});
  }
  return pastes;
}

// Pastes `paste` into every frame of result->frames where it has a usable box,
// as render id result->render_ids.size(); notes and the applied edit go to
// result->summary.
void ApplyPaste(const Paste& paste,
                const cv::Mat& source,
                const BoxSequences& boxes,
                const std::vector<PinholeCamera>& cameras,
                const std::vector<Rigid3d>& cam_from_world,
                const DynamicEditOptions& options,
                const RenderOptions& render_options,
                DynamicEditResult* result) {
  DynamicEditSummary& summary = result->summary;
  const int num_frames = static_cast<int>(cam_from_world.size());
  const PinholeCamera& camera0 = CameraOf(cameras, 0);
  const int W = render_options.width, H = render_options.height;
  const double shift =
      render_options.pixel_convention == PixelConvention::kPixelCenter ? -0.5
                                                                       : 0.0;
  const int32_t render_id = static_cast<int32_t>(result->render_ids.size());
  AppliedEdit applied{paste.kind, paste.id,
                      paste.kind == "insert" ? paste.source_id : "", 0, 0};
  const PinholeCamera cam0 =
      ResizeCamera(camera0, W, H, render_options.pixel_convention);
  const std::optional<Box2d> src =
      PixelBox(*paste.source_track, 0, boxes, cam0, cam_from_world[0], shift);
  if (!src || PixelWindow(*src, W, H).area() == 0) {
    AddNote(&summary, paste.id, -1,
            paste.kind + " skipped: no usable frame-0 box to crop");
    return;
  }
  std::vector<int> missing, skipped;
  for (int f = 0; f < num_frames; ++f) {
    const PinholeCamera cam = ResizeCamera(CameraOf(cameras, f), W, H,
                                           render_options.pixel_convention);
    const std::optional<Box2d> b =
        PixelBox(paste.track, f, boxes, cam, cam_from_world[f], shift);
    if (!b) {
      missing.push_back(f);
      continue;
    }
    if (b->Clipped(W, H).Area() < std::max(options.min_box_area_px, 1e-9)) {
      skipped.push_back(f);
      continue;
    }
    if (PasteFeathered(source, *src, *b, &result->frames[f].rgb,
                       &result->frames[f].instance, render_id)) {
      ++applied.frames_shown;
    } else {
      skipped.push_back(f);
    }
  }
  if (!missing.empty())
    AddNote(&summary, paste.id, -1,
            "not pasted in frames without a box: " + FrameList(missing));
  if (!skipped.empty())
    AddNote(&summary, paste.id, -1,
            "box empty or outside the image, skipped in frames: " +
                FrameList(skipped));
  if (!paste.track.interpolated.empty())
    AddNote(
        &summary, paste.id, -1,
        "boxes interpolated in frames: " + FrameList(paste.track.interpolated));
  result->render_ids.push_back(paste.id);
  summary.edits.push_back(applied);
}

// Pasted pixels are valid; the instance maps are dropped unless wanted.
void MarkPastedPixelsValid(bool want_instance,
                           std::vector<RenderedFrame>* frames) {
  for (RenderedFrame& frame : *frames) {
    const int32_t* inst = frame.instance.ptr<int32_t>();
    uint8_t* mask = frame.mask.ptr<uint8_t>();
    const size_t npix = frame.mask.total();
    for (size_t p = 0; p < npix; ++p)
      if (inst[p] >= 0) mask[p] = kMaskValid;
    if (!want_instance) frame.instance.release();
  }
}

}  // namespace

cv::Mat FeatherAlpha(int width, int height) {
  cv::Mat alpha = cv::Mat::ones(height, width, CV_32F);
  if (width <= 0 || height <= 0) return alpha;
  const cv::Mat k1 = (cv::Mat_<float>(5, 1) << 1, 4, 6, 4, 1) / 16.0f;
  cv::Mat out;
  cv::sepFilter2D(alpha, out, CV_32F, k1, k1, cv::Point(-1, -1), 0,
                  cv::BORDER_CONSTANT);
  return out;
}

bool PasteFeathered(const cv::Mat& source,
                    const Box2d& source_box,
                    const Box2d& target_box,
                    cv::Mat* target,
                    cv::Mat* instance,
                    int32_t id) {
  GEODRIVE_CHECK_INPUT(source.type() == CV_8UC3 && target->type() == CV_8UC3,
                       "paste: images must be RGB CV_8UC3");
  if (!source_box.IsFinite() || !target_box.IsFinite()) return false;
  const cv::Rect src = PixelWindow(source_box, source.cols, source.rows);
  if (src.width <= 0 || src.height <= 0) return false;
  // Unclamped target window (upstream: int() truncation).
  const int x0 = static_cast<int>(std::trunc(target_box.xmin));
  const int y0 = static_cast<int>(std::trunc(target_box.ymin));
  const int x1 = static_cast<int>(std::trunc(target_box.xmax));
  const int y1 = static_cast<int>(std::trunc(target_box.ymax));
  const int tw = x1 - x0, th = y1 - y0;
  if (tw <= 0 || th <= 0) return false;
  const cv::Rect full(x0, y0, tw, th);
  const cv::Rect visible = full & cv::Rect(0, 0, target->cols, target->rows);
  if (visible.width <= 0 || visible.height <= 0) return false;
  // Guard absurd sizes (a box thousands of times the image): resize only what
  // is visible.
  const double sx = double(src.width) / tw, sy = double(src.height) / th;
  cv::Mat patch;
  if (double(tw) * th <= 64.0 * target->total() + 1e6) {
    cv::Mat resized;
    cv::resize(source(src), resized, cv::Size(tw, th), 0, 0, cv::INTER_LINEAR);
    patch = resized(cv::Rect(visible.x - x0, visible.y - y0, visible.width,
                             visible.height));
  } else {
    // Equivalent bilinear sampling (half-pixel centres) of the visible part
    // only.
    cv::Mat mapx(visible.height, visible.width, CV_32F),
        mapy(visible.height, visible.width, CV_32F);
    for (int r = 0; r < visible.height; ++r) {
      for (int c = 0; c < visible.width; ++c) {
        mapx.at<float>(r, c) =
            float((visible.x - x0 + c + 0.5) * sx - 0.5 + src.x);
        mapy.at<float>(r, c) =
            float((visible.y - y0 + r + 0.5) * sy - 0.5 + src.y);
      }
    }
    cv::remap(source, patch, mapx, mapy, cv::INTER_LINEAR,
              cv::BORDER_REPLICATE);
  }
  const cv::Mat alpha = FeatherAlpha(visible.width, visible.height);
  for (int r = 0; r < visible.height; ++r) {
    const cv::Vec3b* p = patch.ptr<cv::Vec3b>(r);
    const float* a = alpha.ptr<float>(r);
    cv::Vec3b* t = target->ptr<cv::Vec3b>(visible.y + r) + visible.x;
    int32_t* inst =
        instance ? instance->ptr<int32_t>(visible.y + r) + visible.x : nullptr;
    for (int c = 0; c < visible.width; ++c) {
      for (int ch = 0; ch < 3; ++ch) {
        t[c][ch] = cv::saturate_cast<uint8_t>(a[c] * p[c][ch] +
                                              (1.0f - a[c]) * t[c][ch]);
      }
      if (inst && a[c] >= 0.5f) inst[c] = id;
    }
  }
  return true;
}

namespace dynamic_edit_internal {

DynamicEditResult Render2d(const PointCloud& cloud_in_world,
                           const std::vector<PinholeCamera>& cameras,
                           const std::vector<Rigid3d>& cam_from_world,
                           const BoxSequences& boxes,
                           const std::vector<ObjectEdit>& edits,
                           const DynamicEditOptions& options,
                           RenderOptions render_options) {
  DynamicEditResult result;
  DynamicEditSummary& summary = result.summary;
  summary.mode = EditMode::k2d;
  const int num_frames = static_cast<int>(cam_from_world.size());
  summary.num_frames = num_frames;
  const EditPlan plan = PlanEdits(boxes, edits);
  const PinholeCamera& camera0 = CameraOf(cameras, 0);

  std::vector<Track> tracks;
  for (const BoxSequence& s : boxes.instances)
    tracks.push_back(BuildTrack(s, num_frames, options.interpolate_missing));

  const PointCloud background = RemoveFrame0BoxPoints(
      cloud_in_world, camera0, cam_from_world[0], boxes, tracks, &summary);

  // 2. Static render (the instance map marks pasted pixels; dropped at the end
  // unless asked for).
  const bool want_instance = render_options.output_instance;
  render_options.output_instance = true;
  result.frames =
      RenderBackground(background, cameras, cam_from_world, render_options);

  const cv::Mat source = CropSource(cloud_in_world, cameras, cam_from_world,
                                    options, render_options);

  // 4. Paste, instances in order, then inserted copies.
  const std::vector<Paste> pastes =
      PlanPastes(boxes, tracks, plan, options, num_frames, &summary);
  for (const Paste& paste : pastes) {
    ApplyPaste(paste, source, boxes, cameras, cam_from_world, options,
               render_options, &result);
  }
  MarkPastedPixelsValid(want_instance, &result.frames);
  summary.num_objects = static_cast<int>(result.render_ids.size());
  return result;
}

}  // namespace dynamic_edit_internal
}  // namespace geodrive
