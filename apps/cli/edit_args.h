#pragma once
// CLI glue of dynamic editing (render/dynamic_edit.h), shared by both binaries
// (part of geodrive_cli, outside the render library): the edit arguments of
// `geodrive render` / `geodrive generate`, their parsing into ObjectEdits and
// the edited render.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/point_cloud.h"
#include "geometry/rigid3.h"
#include "render/boxes.h"
#include "render/dynamic_edit.h"
#include "render/renderer.h"

namespace geodrive {

// ---- CLI glue (`geodrive render --boxes FILE [--edit-mode 2d|3d] [--remove
// ID]...
//      [--insert ID:FILE]... [--move ID:FILE]...`).
struct EditCliArgs {
  std::string boxes_path;
  std::string edit_mode = "3d";
  std::vector<std::string> remove;  // instance ids
  std::vector<std::string>
      insert;  // "ID:FILE": copy ID along FILE's single box sequence
  std::vector<std::string>
      move;  // "ID:FILE": ID follows FILE's single box sequence
};

// Reads the boxes and edit files named in `args` and turns them into edits;
// throws InputError naming the argument or file on a problem.
std::vector<ObjectEdit> ParseEditArgs(const EditCliArgs& args,
                                      BoxSequences* boxes);

// Reads `args`, then RenderWithDynamicEdits. `frame0_image` (optional) is the
// 2D crop source.
DynamicEditResult ApplyEditsAndRender(
    const EditCliArgs& args,
    const PointCloud& cloud_in_world,
    const std::vector<PinholeCamera>& cameras,
    const std::vector<Rigid3d>& cam_from_world,
    const RenderOptions& render_options,
    const cv::Mat& frame0_image = cv::Mat());

}  // namespace geodrive
