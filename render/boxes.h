#pragma once
// Object box sequences for dynamic editing: per instance, per frame, a 2D box
// in a stated image size and optionally a 3D box in the world frame.
//
// File format (JSON, schema data_schema/boxes.schema.json):
//   {"format": "geodrive-boxes", "version": 1, "image_width": 1600,
//   "image_height": 900,
//    "num_frames": 25, "units": "metres",
//    "instances": [{"id": "car-1", "category": "vehicle.car", "frames": [
//        {"frame": 0, "box_2d": [xmin, ymin, xmax, ymax], "visibility": 0.9,
//         "box_3d": {"center": [x, y, z], "size": [w, l, h], "rotation_wxyz":
//         [w, x, y, z]}},
//        ...]}]}
//
// Conventions:
//  - 2D boxes are in pixels of an image of image_width x image_height, in the
//  coordinates that
//    projecting with the camera's K gives (kIntegerIndex: pixel i has its
//    centre at i; nuScenes `view_points`), e.g. the axis-aligned min/max of the
//    projected 3D-box corners as upstream GeoDrive computes them from nuScenes
//    1600x900 corners. The pixels a box covers are, as upstream (int()
//    truncation, clamped), columns floor(xmin) .. floor(xmax) - 1 and rows
//    floor(ymin) .. floor(ymax) - 1. Boxes are scaled by (W / image_width, H /
//    image_height) to another image size (a plain resize, as upstream does).
//  - 3D boxes follow nuScenes: `center` in the world frame, `size` = [width,
//  length, height],
//    `rotation_wxyz` = world_from_box as a unit quaternion, scalar FIRST. The
//    box frame has x forward (along the length), y left (along the width), z
//    up.
//  - A frame absent from an instance's list means "not annotated / not visible"
//  in that frame.
//  - Frames are 0-based indices into the clip (0 .. num_frames - 1).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "geometry/box3d.h"
#include "geometry/camera.h"
#include "geometry/rigid3.h"

namespace geodrive {

// Axis-aligned 2D box [xmin, ymin, xmax, ymax] in pixels (see the file
// comment).
struct Box2d {
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;

  double width() const { return xmax - xmin; }
  double height() const { return ymax - ymin; }
  double Area() const;  // 0 for an empty or inverted box
  bool IsFinite() const;
  // xmin <= xmax and ymin <= ymax.
  bool IsOrdered() const;
  // The box scaled by (sx, sy).
  Box2d Scaled(double sx, double sy) const;
  // Intersection with [0, width] x [0, height] (may be empty: Area() == 0).
  Box2d Clipped(int width, int height) const;
};

// Interpolates two 2D boxes coordinate-wise.
Box2d Interpolate(const Box2d& a, const Box2d& b, double t);

// The 2D box (min/max of the projected corners, kIntegerIndex coordinates as in
// Box2d) of a 3D box seen by `camera` at cam_from_world. Corners with camera z
// <= near are dropped (as nuScenes tools do for boxes partly behind the
// camera); returns nullopt when no corner is in front.
std::optional<Box2d> ProjectBox3d(const Box3d& box,
                                  const PinholeCamera& camera,
                                  const Rigid3d& cam_from_world,
                                  double near = 0.1);

struct BoxFrame {
  int frame = 0;
  std::optional<Box2d> box_2d;
  std::optional<Box3d> box_3d;
  std::optional<double> visibility;  // fraction in [0, 1]
};

struct BoxSequence {
  std::string
      id;  // instance id (nuScenes instance token, or any unique string)
  std::string category;          // e.g. "vehicle.car"; may be empty
  std::vector<BoxFrame> frames;  // sorted by frame, unique frame indices

  // The entry of `frame`, or nullptr if the frame is not annotated.
  const BoxFrame* Find(int frame) const;
  // True if every entry has a 3D box.
  bool HasAll3d() const;
};

struct BoxSequences {
  int image_width = 1600;
  int image_height = 900;
  int num_frames = 25;
  std::string units =
      "metres";  // units of the 3D boxes ("metres", "monst3r", ...)
  std::vector<BoxSequence> instances;

  // The instance with `id`, or nullptr.
  const BoxSequence* Find(const std::string& id) const;
  // Throws InputError("<what>: ...") on: image size outside 1..16384,
  // num_frames < 1, an empty or duplicate instance id, a frame index outside
  // [0, num_frames), duplicate or unsorted frames, an entry with neither a 2D
  // nor a 3D box, a non-finite or inverted 2D box (xmin > xmax or ymin > ymax),
  // an invalid 3D box (non-finite, size <= 0, non-unit quaternion), visibility
  // outside [0, 1]. Zero-area 2D boxes and boxes outside the image are allowed
  // here (the editor skips them with a note).
  void Check(const std::string& what = "boxes") const;
};

// Reads a boxes file; throws InputError naming the file and the JSON location
// of the problem.
BoxSequences ReadBoxesJson(const std::string& path);
// Writes a boxes file (atomically: a temporary file renamed into place). Calls
// Check() first.
void WriteBoxesJson(const std::string& path, const BoxSequences& boxes);

}  // namespace geodrive
