// CLI glue of dynamic editing (dynamic_edit_cli.h): parses --boxes,
// --edit-mode, --remove, --insert and --move into edits and renders with them.

#include "apps/cli/edit_args.h"

#include <string>
#include <vector>

#include "geometry/util/status.h"
#include "render/boxes.h"
#include "render/dynamic_edit.h"

namespace geodrive {
namespace {

// One --insert / --move value "ID:FILE" (`flag` names the option): ID must be
// an instance of `boxes` (read from args.boxes_path) and FILE a boxes file
// with exactly one instance and the same frame count; its 2D boxes are
// rescaled to the main file's image size.
ObjectEdit ParseEditSpec(const std::string& spec,
                         ObjectEditKind kind,
                         const char* flag,
                         const EditCliArgs& args,
                         const BoxSequences& boxes) {
  const size_t colon = spec.find(':');
  GEODRIVE_CHECK_INPUT(
      colon != std::string::npos && colon > 0 && colon + 1 < spec.size(), flag,
      " ", spec, ": expected ID:FILE");
  ObjectEdit e;
  e.kind = kind;
  e.instance = spec.substr(0, colon);
  const std::string file = spec.substr(colon + 1);
  GEODRIVE_CHECK_INPUT(boxes.Find(e.instance) != nullptr, flag, " ", spec,
                       ": no instance '", e.instance, "' in ", args.boxes_path);
  const BoxSequences seq = ReadBoxesJson(file);
  GEODRIVE_CHECK_INPUT(seq.instances.size() == 1, file, ": ", flag,
                       " needs a boxes file with exactly one instance, found ",
                       seq.instances.size());
  GEODRIVE_CHECK_INPUT(seq.num_frames == boxes.num_frames, file,
                       ": num_frames ", seq.num_frames, " differs from ",
                       args.boxes_path, " (", boxes.num_frames, ")");
  e.sequence = seq.instances[0];
  // Express the new 2D boxes in the main file's image size.
  const double sx = double(boxes.image_width) / seq.image_width;
  const double sy = double(boxes.image_height) / seq.image_height;
  for (BoxFrame& f : e.sequence.frames)
    if (f.box_2d) f.box_2d = f.box_2d->Scaled(sx, sy);
  return e;
}

}  // namespace

std::vector<ObjectEdit> ParseEditArgs(const EditCliArgs& args,
                                      BoxSequences* boxes) {
  GEODRIVE_CHECK_INPUT(!args.boxes_path.empty(),
                       "--boxes: a boxes file is required for edits");
  *boxes = ReadBoxesJson(args.boxes_path);
  ParseEditMode(args.edit_mode);
  std::vector<ObjectEdit> edits;
  for (const std::string& id : args.remove) {
    ObjectEdit e;
    e.kind = ObjectEditKind::kRemove;
    e.instance = id;
    GEODRIVE_CHECK_INPUT(boxes->Find(id) != nullptr, "--remove ", id,
                         ": no instance '", id, "' in ", args.boxes_path);
    edits.push_back(e);
  }
  for (const std::string& s : args.insert)
    edits.push_back(
        ParseEditSpec(s, ObjectEditKind::kInsert, "--insert", args, *boxes));
  for (const std::string& s : args.move)
    edits.push_back(
        ParseEditSpec(s, ObjectEditKind::kMove, "--move", args, *boxes));
  return edits;
}

DynamicEditResult ApplyEditsAndRender(
    const EditCliArgs& args,
    const PointCloud& cloud_in_world,
    const std::vector<PinholeCamera>& cameras,
    const std::vector<Rigid3d>& cam_from_world,
    const RenderOptions& render_options,
    const cv::Mat& frame0_image) {
  BoxSequences boxes;
  const std::vector<ObjectEdit> edits = ParseEditArgs(args, &boxes);
  DynamicEditOptions options;
  options.mode = ParseEditMode(args.edit_mode);
  options.frame0_image = frame0_image;
  options.num_threads = render_options.num_threads;
  return RenderWithDynamicEdits(cloud_in_world, cameras, cam_from_world, boxes,
                                edits, options, render_options);
}

}  // namespace geodrive
