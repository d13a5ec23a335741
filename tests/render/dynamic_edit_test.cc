#include "render/dynamic_edit.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <set>
#include <string>

#include "apps/cli/edit_args.h"
#include "geometry/image_io.h"
#include "geometry/point_cloud_io.h"
#include "geometry/trajectory_json.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "tests/render/edit_test_scene.h"

namespace geodrive {
namespace {

using test_scene::MaskIoU;
using test_scene::Scene;

// Built once: ray casting 25 frames of true masks is the expensive part of
// these tests.
const Scene& TestScene() {
  static const Scene* scene = new Scene(test_scene::MakeScene(5));
  return *scene;
}

const std::vector<cv::Mat>& TrueMasks() {
  static const std::vector<cv::Mat>* masks = [] {
    auto* m = new std::vector<cv::Mat>;
    for (int t = 0; t < TestScene().boxes.num_frames; ++t)
      m->push_back(test_scene::TrueInstanceMask(TestScene(), t));
    return m;
  }();
  return *masks;
}

RenderOptions TestRenderOptions(const Scene& scene) {
  RenderOptions o;
  o.width = scene.camera.width;
  o.height = scene.camera.height;
  o.mode = RenderMode::kZBuffer;
  o.radius_px = 0;
  o.hole_fill = false;  // the paper's z-buffer: one pixel per point, no filling
  o.far = 1000;
  o.output_instance = true;  // the tests score the per-pixel object ids
  return o;
}

int RenderIdOf(const DynamicEditResult& r, const std::string& id) {
  for (size_t k = 0; k < r.render_ids.size(); ++k)
    if (r.render_ids[k] == id) return static_cast<int>(k);
  return -100;
}

bool HasNote(const DynamicEditSummary& s,
             const std::string& instance,
             const std::string& text) {
  for (const EditNote& n : s.notes)
    if (n.instance == instance && n.message.find(text) != std::string::npos)
      return true;
  return false;
}

// A vehicle-frame is scored when the vehicle's visible true mask has at least
// this many pixels: below ~10 x 10 px a one-pixel boundary error alone costs
// ~0.2 IoU (pixel quantization of any point renderer, not geometry), e.g. the
// last sliver of v3 disappearing behind v2.
constexpr int kMinTrueArea = 100;

// Per-frame IoUs of every vehicle visible in frame 0, for a result.
std::vector<std::vector<double>> VehicleIoUs(const Scene& scene,
                                             const DynamicEditResult& r) {
  std::vector<std::vector<double>> ious(scene.vehicles.size());
  for (size_t k = 0; k < scene.vehicles.size(); ++k) {
    int area0 = 0;
    MaskIoU(TrueMasks()[0], static_cast<int>(k), TrueMasks()[0],
            static_cast<int>(k), &area0);
    if (area0 < kMinTrueArea) continue;
    const int rid = RenderIdOf(r, scene.vehicles[k].id);
    for (size_t t = 0; t < TrueMasks().size(); ++t) {
      int area = 0;
      const double iou = MaskIoU(r.frames[t].instance, rid, TrueMasks()[t],
                                 static_cast<int>(k), &area);
      ious[k].push_back(area >= kMinTrueArea ? iou : -1.0);
    }
  }
  return ious;
}

TEST(DynamicEdit, ThreeDModeMatchesTrueVehicleMasksIncludingOcclusion) {
  const Scene& scene = TestScene();
  const RenderOptions ro = TestRenderOptions(scene);
  DynamicEditOptions o3;
  o3.mode = EditMode::k3d;
  const DynamicEditResult r3 =
      RenderWithDynamicEdits(scene.cloud, {scene.camera}, scene.cam_from_world,
                             scene.boxes, {}, o3, ro);
  DynamicEditOptions o2;
  o2.mode = EditMode::k2d;
  o2.frame0_image = scene.frame0_rgb;
  const DynamicEditResult r2 =
      RenderWithDynamicEdits(scene.cloud, {scene.camera}, scene.cam_from_world,
                             scene.boxes, {}, o2, ro);
  std::printf("%s\n%s\n", r3.summary.BriefReport().c_str(),
              r2.summary.BriefReport().c_str());
  EXPECT_EQ(r3.summary.num_objects, 5);
  // 3D boxes in every frame: no ground plane is needed (each box's bottom
  // face is the ground), so none is estimated.
  EXPECT_FALSE(r3.summary.ground_plane.has_value());
  EXPECT_FALSE(r3.summary.ground_plane_estimated);

  // v2 (nearer) passes in front of v3: frames where a part of v3 is hidden by
  // v2.
  Scene solo3 = scene;
  solo3.vehicles = {scene.vehicles[3]};
  std::vector<int> occluded_frames;
  for (int t = 0; t < scene.boxes.num_frames; ++t) {
    const cv::Mat solo = test_scene::TrueInstanceMask(solo3, t);
    const int hidden = cv::countNonZero((solo == 0) & (TrueMasks()[t] == 2));
    if (hidden >= 20) occluded_frames.push_back(t);
  }
  std::printf("v3 partly hidden by v2 in %zu frames\n", occluded_frames.size());
  ASSERT_GE(occluded_frames.size(), 5u)
      << "the scene must contain the occluding pair";

  // Pictures to look at: GEODRIVE_EDIT_TEST_DUMP=<dir> writes frames 0, 12, 24
  // (3d | 2d | true).
  if (const char* dump = std::getenv("GEODRIVE_EDIT_TEST_DUMP")) {
    for (int t : {0, 12, 24}) {
      cv::Mat truth;
      test_scene::TrueInstanceMask(scene, t, &truth);
      cv::Mat row;
      cv::hconcat(
          std::vector<cv::Mat>{r3.frames[t].rgb, r2.frames[t].rgb, truth}, row);
      WriteImageRgb(
          std::string(dump) + "/edit_frame" + std::to_string(t) + ".png", row);
    }
  }
  const auto iou3 = VehicleIoUs(scene, r3);
  const auto iou2 = VehicleIoUs(scene, r2);
  double min3 = 1, sum3 = 0, sum2 = 0;
  int count = 0;
  for (size_t k = 0; k < scene.vehicles.size(); ++k) {
    ASSERT_FALSE(iou3[k].empty())
        << scene.vehicles[k].id << " not visible in frame 0";
    std::string line;
    for (size_t t = 0; t < iou3[k].size(); ++t) {
      if (iou3[k][t] < 0) continue;
      char buf[32];
      std::snprintf(buf, sizeof(buf), " %.2f/%.2f", iou3[k][t], iou2[k][t]);
      line += buf;
      min3 = std::min(min3, iou3[k][t]);
      sum3 += iou3[k][t];
      sum2 += iou2[k][t];
      ++count;
    }
    std::printf("%-12s IoU per frame 3d/2d:%s\n", scene.vehicles[k].id.c_str(),
                line.c_str());
    for (size_t t = 0; t < iou3[k].size(); ++t) {
      if (iou3[k][t] >= 0) {
        EXPECT_GE(iou3[k][t], 0.8) << scene.vehicles[k].id << " frame " << t;
      }
    }
  }
  double min3_occluded = 1, min2_occluded = 1;
  int occluded_scored = 0;
  for (int t : occluded_frames) {
    if (iou3[3][t] < 0) continue;
    ++occluded_scored;
    min3_occluded = std::min(min3_occluded, iou3[3][t]);
    min2_occluded = std::min(min2_occluded, iou2[3][t]);
  }
  std::printf(
      "IoU over %d vehicle-frames: 3d mean %.3f min %.3f | 2d mean %.3f; "
      "v3 while partly hidden by v2 (%d frames): 3d min %.3f, 2d min %.3f\n",
      count, sum3 / count, min3, sum2 / count, occluded_scored, min3_occluded,
      min2_occluded);
  EXPECT_GE(occluded_scored, 5) << "scored frames with v3 partly hidden by v2";
  EXPECT_GE(min3_occluded, 0.8);
  // Sanity: the geometric edit beats the 2D paste on this scene.
  EXPECT_GT(sum3 / count, sum2 / count);
}

// Approached vehicles are drawn magnified: their points carry frame-0
// footprints (render/footprint.h) and become footprint splats, the
// renderer's one mechanism; without them (max_magnification 1) the background
// shows through the magnified vehicles.
TEST(DynamicEdit, MagnifiedVehiclesAreFootprintSplatsWithoutHoles) {
  const Scene& scene = TestScene();
  const RenderOptions ro = TestRenderOptions(scene);
  DynamicEditOptions with;
  DynamicEditOptions without;
  without.max_magnification = 1;
  DynamicEditSummary summary;
  const DynamicScene dyn =
      BuildDynamicScene(scene.cloud, {scene.camera}, scene.cam_from_world,
                        scene.boxes, {}, with, &summary);
  // Footprint of each object point: its camera-0 depth / sqrt(fx fy).
  const Rigid3d& pose0 = scene.cam_from_world[0];
  for (const DynamicObject& object : dyn.objects) {
    ASSERT_EQ(object.points_in_object.footprints.size(),
              object.points_in_object.size());
    const Rigid3d world_from_object0 =
        object.poses[0] ? object.poses[0]->world_from_object : Rigid3d();
    for (size_t i = 0; i < object.points_in_object.size(); i += 97) {
      const double z =
          (pose0 * (world_from_object0 *
                    object.points_in_object.positions[i].cast<double>()))
              .z();
      EXPECT_NEAR(object.points_in_object.footprints[i],
                  z / std::sqrt(scene.camera.fx * scene.camera.fy), 1e-5 * z)
          << object.id;
    }
  }
  const DynamicEditResult r_with =
      RenderWithDynamicEdits(scene.cloud, {scene.camera}, scene.cam_from_world,
                             scene.boxes, {}, with, ro);
  const DynamicEditResult r_without =
      RenderWithDynamicEdits(scene.cloud, {scene.camera}, scene.cam_from_world,
                             scene.boxes, {}, without, ro);
  const auto iou_with = VehicleIoUs(scene, r_with);
  const auto iou_without = VehicleIoUs(scene, r_without);
  // v1 is approached, v4 oncoming: their last visible frame is magnified.
  for (int k : {1, 4}) {
    int last = -1;
    for (size_t t = 0; t < iou_with[k].size(); ++t)
      if (iou_with[k][t] >= 0) last = static_cast<int>(t);
    ASSERT_GE(last, 0) << scene.vehicles[k].id;
    std::printf("%s frame %d IoU with footprints %.3f, one pixel %.3f\n",
                scene.vehicles[k].id.c_str(), last, iou_with[k][last],
                iou_without[k][last]);
    EXPECT_GE(iou_with[k][last], 0.8) << scene.vehicles[k].id;
    EXPECT_GT(iou_with[k][last], iou_without[k][last] + 0.05)
        << scene.vehicles[k].id;
  }
}

TEST(DynamicEdit, ThreeDModeFromTwoDBoxesLiftsOntoTheGround) {
  const Scene& scene = TestScene();
  BoxSequences boxes2d = scene.boxes;
  for (BoxSequence& s : boxes2d.instances)
    for (BoxFrame& f : s.frames) f.box_3d.reset();
  DynamicEditOptions o;
  o.mode = EditMode::k3d;
  const DynamicEditResult r =
      RenderWithDynamicEdits(scene.cloud, {scene.camera}, scene.cam_from_world,
                             boxes2d, {}, o, TestRenderOptions(scene));
  std::printf("%s\n", r.summary.BriefReport().c_str());
  EXPECT_EQ(r.summary.num_objects, 5);
  // 2D boxes only: the ground plane z = 0 is estimated.
  ASSERT_TRUE(r.summary.ground_plane.has_value());
  EXPECT_TRUE(r.summary.ground_plane_estimated);
  EXPECT_NEAR((*r.summary.ground_plane)[2], 1.0, 1e-3);
  EXPECT_NEAR((*r.summary.ground_plane)[3], 0.0, 0.02);
  const auto ious = VehicleIoUs(scene, r);
  for (size_t k = 0; k < scene.vehicles.size(); ++k) {
    double sum = 0, mn = 1;
    int n = 0;
    for (double v : ious[k]) {
      if (v < 0) continue;
      sum += v;
      mn = std::min(mn, v);
      ++n;
    }
    std::printf(
        "%-12s lifted from 2D boxes: IoU mean %.3f min %.3f over %d frames\n",
        scene.vehicles[k].id.c_str(), sum / n, mn, n);
    // Frame 0 is the segmentation itself: the depth cluster must be the
    // vehicle.
    EXPECT_GE(ious[k][0], 0.8) << scene.vehicles[k].id;
    // Lifting only translates (no yaw from 2D boxes) and the box bottom is the
    // nearest corner, so later frames are looser; half the true mask must still
    // be covered.
    EXPECT_GE(sum / n, 0.6) << scene.vehicles[k].id;
  }
}

TEST(DynamicEdit, DynamicMaskRestrictsTwoDBoxSegmentation) {
  // 2D boxes only. A frame-0 dynamic mask (at half resolution, to exercise
  // the scaling) keeps only points on masked pixels; a mask that would leave
  // too few points is ignored with a note.
  const Scene& scene = TestScene();
  BoxSequences boxes2d = scene.boxes;
  for (BoxSequence& seq : boxes2d.instances)
    for (BoxFrame& f : seq.frames) f.box_3d.reset();
  // Mask: the true vehicle pixels of frame 0, eroded so that it differs from
  // what the depth clustering alone finds.
  cv::Mat vehicles = TrueMasks()[0] >= 0;
  cv::erode(vehicles, vehicles, cv::Mat::ones(5, 5, CV_8U));
  cv::Mat half;
  cv::resize(vehicles, half, cv::Size(), 0.5, 0.5, cv::INTER_NEAREST);
  DynamicEditOptions plain_options;
  DynamicEditOptions masked_options;
  masked_options.dynamic_mask = half;
  DynamicEditSummary plain_summary, masked_summary;
  const DynamicScene plain =
      BuildDynamicScene(scene.cloud, {scene.camera}, scene.cam_from_world,
                        boxes2d, {}, plain_options, &plain_summary);
  const DynamicScene masked =
      BuildDynamicScene(scene.cloud, {scene.camera}, scene.cam_from_world,
                        boxes2d, {}, masked_options, &masked_summary);
  ASSERT_EQ(plain.objects.size(), masked.objects.size());
  const PinholeCamera& camera = scene.camera;
  const Rigid3d& pose0 = scene.cam_from_world[0];
  int64_t fewer = 0;
  for (size_t k = 0; k < masked.objects.size(); ++k) {
    const DynamicObject& object = masked.objects[k];
    const bool ignored = HasNote(masked_summary, object.id, "dynamic mask");
    int off_mask = 0;
    for (const Eigen::Vector3f& p : object.points_in_object.positions) {
      // No 3D box: the object frame is the world frame.
      const Eigen::Vector3d c = pose0 * p.cast<double>();
      const int u = static_cast<int>(
          std::floor(camera.fx * c.x() / c.z() + camera.cx + 0.5));
      const int v = static_cast<int>(
          std::floor(camera.fy * c.y() / c.z() + camera.cy + 0.5));
      const int mu = std::min(half.cols - 1, int((u + 0.5) * 0.5));
      const int mv = std::min(half.rows - 1, int((v + 0.5) * 0.5));
      off_mask += half.at<uint8_t>(mv, mu) == 0;
    }
    // The segmentation projects in float, this check in double: a point
    // within rounding of a pixel border may land on the neighbour here.
    if (!ignored) {
      EXPECT_LE(off_mask,
                std::max<int>(2, object.points_in_object.size() / 100))
          << object.id;
    }
    std::printf("%-12s masked %zu of %zu points, %d off the mask%s\n",
                object.id.c_str(), object.points_in_object.size(),
                plain.objects[k].points_in_object.size(), off_mask,
                ignored ? " (mask ignored)" : "");
    EXPECT_LE(object.points_in_object.size(),
              plain.objects[k].points_in_object.size())
        << object.id;
    fewer += static_cast<int64_t>(plain.objects[k].points_in_object.size() -
                                  object.points_in_object.size());
  }
  EXPECT_GT(fewer, 100);  // the mask removed points (eroded rims)
  // An empty mask leaves nothing: ignored for every instance, with notes,
  // and the segmentation is the unmasked one.
  DynamicEditOptions empty_options;
  empty_options.dynamic_mask = cv::Mat::zeros(10, 10, CV_8U);
  DynamicEditSummary empty_summary;
  const DynamicScene empty =
      BuildDynamicScene(scene.cloud, {scene.camera}, scene.cam_from_world,
                        boxes2d, {}, empty_options, &empty_summary);
  ASSERT_EQ(empty.objects.size(), plain.objects.size());
  for (size_t k = 0; k < empty.objects.size(); ++k) {
    EXPECT_TRUE(HasNote(empty_summary, empty.objects[k].id,
                        "dynamic mask leaves too few points"));
    EXPECT_EQ(empty.objects[k].points_in_object.size(),
              plain.objects[k].points_in_object.size());
  }
}

TEST(DynamicEdit, ThreeDBoxSegmentationLeavesRoadPointsAtTheBoxBottom) {
  // Without a ground plane, a 3D box's bottom face is the ground: points
  // within ground_margin of it (the road under and beside the vehicle, inside
  // the box grown by box_margin) stay in the background.
  const Scene& scene = TestScene();
  DynamicEditOptions o;
  DynamicEditSummary summary;
  const DynamicScene dyn =
      BuildDynamicScene(scene.cloud, {scene.camera}, scene.cam_from_world,
                        scene.boxes, {}, o, &summary);
  ASSERT_FALSE(summary.ground_plane.has_value());
  ASSERT_EQ(dyn.objects.size(), scene.vehicles.size());
  int road_in_boxes = 0;
  for (size_t k = 0; k < scene.vehicles.size(); ++k) {
    const Box3d& box0 = scene.vehicles[k].boxes[0];
    for (const Eigen::Vector3f& p : scene.cloud.positions)
      road_in_boxes += box0.Contains(p.cast<double>(), o.box_margin) &&
                       p.z() < o.ground_margin;
    const DynamicObject& object = dyn.objects[k];
    ASSERT_TRUE(object.poses[0].has_value());
    float lowest = 1e9f;
    for (const Eigen::Vector3f& p : object.points_in_object.positions) {
      const Eigen::Vector3d w =
          object.poses[0]->world_from_object *
          object.poses[0]->scale.cwiseProduct(p.cast<double>());
      lowest = std::min(lowest, static_cast<float>(w.z()));
    }
    // The ground is z = 0 and every box sits on it.
    EXPECT_GT(lowest, o.ground_margin - 1e-4) << object.id;
  }
  EXPECT_GT(road_in_boxes, 100);  // there were road points to leave out
}

TEST(DynamicEdit, BackgroundPixelsHaveNoInstanceEvenIfTheCloudCarriesIds) {
  const Scene& scene = TestScene();
  PointCloud cloud = scene.cloud;
  cloud.instance_ids.assign(cloud.size(), 99);
  const DynamicEditResult r = RenderWithDynamicEdits(
      cloud, {scene.camera}, scene.cam_from_world, scene.boxes, {},
      DynamicEditOptions(), TestRenderOptions(scene));
  ASSERT_EQ(r.render_ids.size(), 5u);
  int background = 0;
  for (const RenderedFrame& f : r.frames) {
    EXPECT_EQ(cv::countNonZero(f.instance == 99), 0);
    background += cv::countNonZero((f.instance == -1) & (f.mask > 0));
  }
  EXPECT_GT(background, 1000);
}

TEST(DynamicEdit, RemovalLeavesNoPointOfTheObject) {
  const Scene& scene = TestScene();
  const int victim = 1;
  const std::string id = scene.vehicles[victim].id;
  std::set<std::tuple<float, float, float>> victim_points;
  for (size_t i = 0; i < scene.cloud.size(); ++i) {
    if (scene.cloud.instance_ids[i] == victim) {
      const Eigen::Vector3f& p = scene.cloud.positions[i];
      victim_points.insert({p.x(), p.y(), p.z()});
    }
  }
  ASSERT_GT(victim_points.size(), 200u);
  ObjectEdit remove;
  remove.kind = ObjectEditKind::kRemove;
  remove.instance = id;
  DynamicEditOptions o;
  DynamicEditSummary summary;
  const DynamicScene dyn =
      BuildDynamicScene(scene.cloud, {scene.camera}, scene.cam_from_world,
                        scene.boxes, {remove}, o, &summary);
  // Every point of the vehicle was segmented and removed, nothing else.
  EXPECT_EQ(summary.removed_points, static_cast<int64_t>(victim_points.size()));
  EXPECT_EQ(dyn.objects.size(), 4u);
  for (int t = 0; t < dyn.num_frames; ++t) {
    const PointCloud cloud = dyn.ComposeFrame(scene.cloud, t);
    int leaked = 0, in_body = 0;
    for (const Eigen::Vector3f& p : cloud.positions) {
      leaked += victim_points.count({p.x(), p.y(), p.z()});
      const Box3d& b = scene.vehicles[victim].boxes[t];
      in_body += b.Contains(p.cast<double>(), 0.05) && p.z() > 0.1;
    }
    EXPECT_EQ(leaked, 0) << "frame " << t;
    EXPECT_EQ(in_body, 0) << "frame " << t;
  }
  // Rendered: the removed id draws nothing; the others still do.
  const DynamicEditResult r = RenderWithDynamicEdits(
      scene.cloud, {scene.camera}, scene.cam_from_world, scene.boxes, {remove},
      o, TestRenderOptions(scene));
  EXPECT_EQ(RenderIdOf(r, id), -100);
  bool found = false;
  for (const AppliedEdit& e : r.summary.edits) {
    if (e.kind == "remove" && e.instance == id) {
      found = true;
      EXPECT_EQ(e.num_points, static_cast<int64_t>(victim_points.size()));
    }
  }
  EXPECT_TRUE(found);
  const std::string js = r.summary.ToJson();
  EXPECT_NE(js.find("\"kind\":\"remove\""), std::string::npos) << js;
}

Box3d Scaled(const Box3d& b, double s) {
  Box3d out = b;
  out.size *= s;
  out.center.z() = out.size[2] / 2;
  return out;
}

TEST(DynamicEdit, InsertAndMovePlaceThePointsInsideTheNewBoxes) {
  const Scene& scene = TestScene();
  // Copy v0 into the left lane, 10 % larger, turning; move v1 to a new path.
  BoxSequence copy;
  copy.id = "v0-copy";
  BoxSequence path;
  path.id = "ignored";
  for (int t = 0; t < scene.boxes.num_frames; ++t) {
    BoxFrame a;
    a.frame = t;
    a.box_3d = Scaled(
        test_scene::YawBox(scene.vehicles[0].size, 14 + 0.3 * t, 6.5, 0.02 * t),
        1.1);
    copy.frames.push_back(a);
    if (t % 3 == 0 || t == 24) {  // sparse keyframes: the rest interpolated
      BoxFrame b;
      b.frame = t;
      b.box_3d = test_scene::YawBox(scene.vehicles[1].size, 26 - 0.2 * t, 1.0,
                                    -0.03 * t);
      path.frames.push_back(b);
    }
  }
  ObjectEdit insert{ObjectEditKind::kInsert, scene.vehicles[0].id, copy};
  ObjectEdit move{ObjectEditKind::kMove, scene.vehicles[1].id, path};
  DynamicEditOptions o;
  DynamicEditSummary summary;
  const DynamicScene dyn =
      BuildDynamicScene(scene.cloud, {scene.camera}, scene.cam_from_world,
                        scene.boxes, {insert, move}, o, &summary);
  ASSERT_EQ(dyn.objects.size(), 6u);
  const DynamicObject& inserted = dyn.objects.back();
  EXPECT_EQ(inserted.id, "v0-copy");
  EXPECT_EQ(inserted.source_id, scene.vehicles[0].id);
  const DynamicObject& moved = dyn.objects[1];
  EXPECT_EQ(moved.id, scene.vehicles[1].id);
  EXPECT_TRUE(HasNote(summary, scene.vehicles[1].id, "interpolated"));
  for (int t = 0; t < dyn.num_frames; ++t) {
    const PointCloud cloud = dyn.ComposeFrame(scene.cloud, t);
    // The moved object's box at t: interpolation of the keyframes is exact for
    // this linear path.
    const Box3d move_box = test_scene::YawBox(scene.vehicles[1].size,
                                              26 - 0.2 * t, 1.0, -0.03 * t);
    int n_ins = 0, out_ins = 0, n_mov = 0, out_mov = 0;
    for (size_t i = 0; i < cloud.size(); ++i) {
      const Eigen::Vector3d p = cloud.positions[i].cast<double>();
      if (cloud.instance_ids[i] == inserted.render_id) {
        ++n_ins;
        // Segmentation margin 0.05, scaled by 1.1, plus float rounding.
        out_ins += !copy.frames[t].box_3d->Contains(p, 0.055 + 1e-4);
      } else if (cloud.instance_ids[i] == moved.render_id) {
        ++n_mov;
        out_mov += !move_box.Contains(p, 0.05 + 1e-4);
      }
    }
    // Each point is drawn once (magnified ones as footprint splats).
    EXPECT_EQ(n_ins, static_cast<int>(inserted.points_in_object.size()))
        << "frame " << t;
    EXPECT_EQ(out_ins, 0) << "frame " << t;
    EXPECT_EQ(n_mov, static_cast<int>(moved.points_in_object.size()))
        << "frame " << t;
    EXPECT_EQ(out_mov, 0) << "frame " << t;
  }
  // The original v0 is still there, and the copy is drawn.
  const DynamicEditResult r = RenderWithDynamicEdits(
      scene.cloud, {scene.camera}, scene.cam_from_world, scene.boxes,
      {insert, move}, o, TestRenderOptions(scene));
  const int rid = RenderIdOf(r, "v0-copy");
  ASSERT_GE(rid, 0);
  for (int t : {0, 12, 24}) {
    EXPECT_GT(cv::countNonZero(r.frames[t].instance == rid), 200)
        << "frame " << t;
    EXPECT_GT(cv::countNonZero(r.frames[t].instance ==
                               RenderIdOf(r, scene.vehicles[0].id)),
              200);
  }
}

TEST(DynamicEdit, FeatherAlphaHasUpstreamNumbers) {
  const cv::Mat a = FeatherAlpha(20, 10);
  EXPECT_FLOAT_EQ(a.at<float>(5, 0), 11.0f / 16);    // edge 0.6875
  EXPECT_FLOAT_EQ(a.at<float>(5, 1), 15.0f / 16);    // second 0.9375
  EXPECT_FLOAT_EQ(a.at<float>(0, 0), 121.0f / 256);  // corner 0.4727
  EXPECT_FLOAT_EQ(a.at<float>(5, 10), 1.0f);
  EXPECT_FLOAT_EQ(a.at<float>(9, 19), 121.0f / 256);
}

TEST(DynamicEdit, PasteFeatheredBlendsResizesAndClips) {
  cv::Mat source(40, 40, CV_8UC3, cv::Scalar(200, 100, 40));
  cv::Mat target = cv::Mat::zeros(30, 30, CV_8UC3);
  cv::Mat instance(30, 30, CV_32S, cv::Scalar(-1));
  // Constant crop 10x10 -> target box 16x8 at (4, 6): value = round(alpha * c).
  ASSERT_TRUE(PasteFeathered(source, Box2d{5, 5, 15, 15},
                             Box2d{4.7, 6.2, 20.9, 14.99}, &target, &instance,
                             7));
  EXPECT_EQ(target.at<cv::Vec3b>(10, 12), cv::Vec3b(200, 100, 40));  // interior
  EXPECT_EQ(target.at<cv::Vec3b>(10, 4)[0],
            cvRound(200 * 11.0 / 16));  // left edge
  EXPECT_EQ(target.at<cv::Vec3b>(6, 4)[0],
            cvRound(200 * 121.0 / 256));                       // corner
  EXPECT_EQ(target.at<cv::Vec3b>(10, 3), cv::Vec3b(0, 0, 0));  // outside
  EXPECT_EQ(target.at<cv::Vec3b>(10, 20),
            cv::Vec3b(0, 0, 0));              // trunc(20.9)=20
  EXPECT_EQ(instance.at<int32_t>(6, 4), -1);  // alpha 0.47
  EXPECT_EQ(instance.at<int32_t>(6, 5), 7);   // alpha 0.64
  // Partly outside: alpha made for the visible part (image edge feathered too).
  cv::Mat t2 = cv::Mat::zeros(30, 30, CV_8UC3);
  ASSERT_TRUE(
      PasteFeathered(source, Box2d{0, 0, 40, 40}, Box2d{-10, 10, 10, 20}, &t2));
  EXPECT_EQ(t2.at<cv::Vec3b>(15, 0)[0], cvRound(200 * 11.0 / 16));
  EXPECT_EQ(t2.at<cv::Vec3b>(15, 10), cv::Vec3b(0, 0, 0));
  // Bilinear: a horizontal ramp crop doubled equals cv::resize INTER_LINEAR in
  // the interior.
  cv::Mat ramp(10, 10, CV_8UC3);
  for (int c = 0; c < 10; ++c) ramp.col(c).setTo(cv::Scalar(20 * c, 0, 0));
  cv::Mat t3 = cv::Mat::zeros(30, 30, CV_8UC3);
  ASSERT_TRUE(
      PasteFeathered(ramp, Box2d{0, 0, 10, 10}, Box2d{0, 0, 20, 20}, &t3));
  // Column 9 of the 20-wide resize samples x = (9 + 0.5) / 2 - 0.5 = 4.25
  // -> 85.
  EXPECT_EQ(t3.at<cv::Vec3b>(10, 9)[0], 85);
  // Degenerate boxes: nothing pasted.
  cv::Mat t4 = cv::Mat::zeros(30, 30, CV_8UC3);
  EXPECT_FALSE(
      PasteFeathered(source, Box2d{5, 5, 5, 15}, Box2d{0, 0, 10, 10}, &t4));
  EXPECT_FALSE(
      PasteFeathered(source, Box2d{5, 5, 15, 15}, Box2d{40, 40, 50, 50}, &t4));
  EXPECT_FALSE(
      PasteFeathered(source, Box2d{5, 5, 15, 15}, Box2d{3, 3, 3.5, 9}, &t4));
  EXPECT_EQ(cv::countNonZero(t4.reshape(1)), 0);
}

TEST(DynamicEdit, TwoDModeDeletesTheFrameZeroBoxRegionPoints) {
  const Scene& scene = TestScene();
  DynamicEditOptions o;
  o.mode = EditMode::k2d;
  o.frame0_image = scene.frame0_rgb;
  const RenderOptions ro = TestRenderOptions(scene);
  const DynamicEditResult r =
      RenderWithDynamicEdits(scene.cloud, {scene.camera}, scene.cam_from_world,
                             scene.boxes, {}, o, ro);
  // Expected: points whose frame-0 pixel lies in a union of the floor()ed
  // windows of the boxes scaled from the 2x image (the cloud is the frame-0
  // pointmap: one point per hit pixel).
  cv::Mat hit = cv::Mat::zeros(scene.camera.height, scene.camera.width, CV_8U);
  cv::Mat in_box = hit.clone();
  for (const BoxSequence& s : scene.boxes.instances) {
    const Box2d b = s.Find(0)->box_2d->Scaled(0.5, 0.5);
    const int x0 = std::max(0, int(std::floor(b.xmin))),
              y0 = std::max(0, int(std::floor(b.ymin)));
    const int x1 = std::min(scene.camera.width, int(std::floor(b.xmax)));
    const int y1 = std::min(scene.camera.height, int(std::floor(b.ymax)));
    in_box(cv::Rect(x0, y0, x1 - x0, y1 - y0)).setTo(1);
  }
  const Rigid3d world_from_cam0 = scene.cam_from_world[0].Inverse();
  (void)world_from_cam0;
  int64_t expected = 0;
  for (const Eigen::Vector3f& p : scene.cloud.positions) {
    const Eigen::Vector2d uv =
        scene.camera.Project(scene.cam_from_world[0] * p.cast<double>());
    expected += in_box.at<uint8_t>(int(std::floor(uv.y() + 0.5)),
                                   int(std::floor(uv.x() + 0.5)));
  }
  EXPECT_EQ(r.summary.removed_points, expected);
  EXPECT_GT(expected, 1000);
  // Frame 0: the pasted crops restore the real image inside the boxes (alpha =
  // 1 interior).
  const BoxSequence& s0 = scene.boxes.instances[0];
  const Box2d b0 = s0.Find(0)->box_2d->Scaled(0.5, 0.5);
  const int cx = int((b0.xmin + b0.xmax) / 2),
            cy = int((b0.ymin + b0.ymax) / 2);
  EXPECT_EQ(r.frames[0].rgb.at<cv::Vec3b>(cy, cx),
            scene.frame0_rgb.at<cv::Vec3b>(cy, cx));
  EXPECT_EQ(r.summary.edits.size(), 5u);
  for (const AppliedEdit& e : r.summary.edits)
    EXPECT_EQ(e.frames_shown, 25) << e.instance;
}

TEST(DynamicEdit, BadBoxesAreSkippedWithNotes) {
  const Scene& scene = TestScene();
  BoxSequences boxes = scene.boxes;
  BoxSequence& v0 = boxes.instances[0];
  v0.frames[5].box_2d = Box2d{-900, -900, -800, -800};  // outside the image
  v0.frames[5].box_3d.reset();
  v0.frames[3].box_2d = Box2d{400, 300, 400, 340};  // zero area
  v0.frames[3].box_3d.reset();
  BoxSequence& v1 = boxes.instances[1];
  v1.frames.erase(v1.frames.begin() + 10,
                  v1.frames.begin() + 13);  // frames 10..12 missing
  v1.frames.erase(v1.frames.begin() + 17, v1.frames.end());  // 20..24 missing
  BoxSequence ghost;  // no point in frame 0: a box behind the camera
  ghost.id = "ghost";
  BoxFrame g;
  g.frame = 0;
  g.box_3d = test_scene::YawBox(Eigen::Vector3d(2, 4, 1.5), -20, 0, 0);
  ghost.frames.push_back(g);
  BoxSequence late;  // first seen in frame 4
  late.id = "late";
  BoxFrame l;
  l.frame = 4;
  l.box_2d = Box2d{10, 10, 50, 50};
  late.frames.push_back(l);
  const std::string v0_id = v0.id, v1_id = v1.id;
  boxes.instances.push_back(ghost);  // invalidates v0, v1
  boxes.instances.push_back(late);

  const RenderOptions ro = TestRenderOptions(scene);
  DynamicEditOptions o2;
  o2.mode = EditMode::k2d;
  const DynamicEditResult r2 = RenderWithDynamicEdits(
      scene.cloud, {scene.camera}, scene.cam_from_world, boxes, {}, o2, ro);
  for (const EditNote& n : r2.summary.notes)
    std::printf("2d note [%s] %d: %s\n", n.instance.c_str(), n.frame,
                n.message.c_str());
  EXPECT_TRUE(HasNote(r2.summary, v0_id, "skipped in frames: 3,5"));
  EXPECT_TRUE(HasNote(r2.summary, v1_id, "interpolated in frames: 10,11,12"));
  EXPECT_TRUE(HasNote(r2.summary, v1_id,
                      "not pasted in frames without a box: 20,21,22,23,24"));
  EXPECT_TRUE(HasNote(r2.summary, "late", "no box in frame 0"));

  DynamicEditOptions o3;
  const DynamicEditResult r3 = RenderWithDynamicEdits(
      scene.cloud, {scene.camera}, scene.cam_from_world, boxes, {}, o3, ro);
  for (const EditNote& n : r3.summary.notes)
    std::printf("3d note [%s] %d: %s\n", n.instance.c_str(), n.frame,
                n.message.c_str());
  EXPECT_TRUE(HasNote(r3.summary, "ghost", "only 0 point(s) segmented"));
  EXPECT_TRUE(HasNote(r3.summary, "late", "no box in frame 0"));
  EXPECT_TRUE(HasNote(r3.summary, v1_id,
                      "not drawn in frames without a box: 20,21,22,23,24"));
  EXPECT_EQ(r3.summary.num_objects, 5);
  // v0's frame 5 box is off-screen: lifted off-screen, so v0 is not drawn in
  // frame 5.
  const int rid0 = RenderIdOf(r3, v0_id);
  EXPECT_LT(cv::countNonZero(r3.frames[5].instance == rid0), 20);
  // v1 hidden after its last box; interpolated frames still match the truth.
  const int rid1 = RenderIdOf(r3, v1_id);
  EXPECT_EQ(cv::countNonZero(r3.frames[22].instance == rid1), 0);
  for (int t : {10, 11, 12})
    EXPECT_GE(MaskIoU(r3.frames[t].instance, rid1, TrueMasks()[t], 1), 0.8)
        << t;
  // The notes go to render.json.
  EXPECT_NE(r3.summary.ToJson().find("ghost"), std::string::npos);
}

TEST(DynamicEdit, InvalidEditsAndClipsAreRejected) {
  const Scene& scene = TestScene();
  const RenderOptions ro = TestRenderOptions(scene);
  DynamicEditOptions o;
  auto error = [&](const BoxSequences& boxes,
                   const std::vector<ObjectEdit>& edits,
                   std::vector<Rigid3d> poses) -> std::string {
    try {
      RenderWithDynamicEdits(scene.cloud, {scene.camera}, poses, boxes, edits,
                             o, ro);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  std::vector<Rigid3d> short_clip(scene.cam_from_world.begin(),
                                  scene.cam_from_world.begin() + 20);
  EXPECT_NE(error(scene.boxes, {}, short_clip)
                .find("num_frames 25 but the clip has 20"),
            std::string::npos);
  ObjectEdit unknown{ObjectEditKind::kRemove, "nope", {}};
  EXPECT_NE(
      error(scene.boxes, {unknown}, scene.cam_from_world).find("no instance"),
      std::string::npos);
  BoxSequence dup;
  dup.id = scene.vehicles[2].id;
  ObjectEdit clash{ObjectEditKind::kInsert, scene.vehicles[0].id, dup};
  EXPECT_NE(
      error(scene.boxes, {clash}, scene.cam_from_world).find("already used"),
      std::string::npos);
  ObjectEdit twice{ObjectEditKind::kRemove, scene.vehicles[0].id, {}};
  EXPECT_NE(error(scene.boxes, {twice, twice}, scene.cam_from_world)
                .find("already removed"),
            std::string::npos);
  BoxSequence inverted;
  inverted.id = "x";
  inverted.frames.push_back(
      BoxFrame{0, Box2d{10, 10, 5, 20}, std::nullopt, std::nullopt});
  ObjectEdit bad_move{ObjectEditKind::kMove, scene.vehicles[0].id, inverted};
  EXPECT_NE(
      error(scene.boxes, {bad_move}, scene.cam_from_world).find("inverted"),
      std::string::npos);
  EXPECT_THROW(ParseEditMode("4d"), InputError);
}

TEST(DynamicEdit, CliArgumentsAreParsedWithClearErrors) {
  const Scene& scene = TestScene();
  const std::string dir = test::MakeTempDir("edit_cli");
  WriteBoxesJson(dir + "/boxes.json", scene.boxes);
  BoxSequences one = scene.boxes;
  one.instances.resize(1);
  one.instances[0].id = "copy";
  one.image_width =
      scene.boxes.image_width * 2;  // rescaled to the main file's image size
  one.image_height = scene.boxes.image_height * 2;
  WriteBoxesJson(dir + "/copy.json", one);
  EditCliArgs args;
  args.boxes_path = dir + "/boxes.json";
  args.remove = {scene.vehicles[1].id};
  args.insert = {scene.vehicles[0].id + ":" + dir + "/copy.json"};
  BoxSequences boxes;
  const std::vector<ObjectEdit> edits = ParseEditArgs(args, &boxes);
  ASSERT_EQ(edits.size(), 2u);
  EXPECT_EQ(edits[1].sequence.id, "copy");
  EXPECT_DOUBLE_EQ(edits[1].sequence.frames[0].box_2d->xmax,
                   one.instances[0].frames[0].box_2d->xmax / 2);
  auto error = [&](EditCliArgs a) -> std::string {
    try {
      ParseEditArgs(a, &boxes);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  EditCliArgs a = args;
  a.insert = {"no-colon"};
  EXPECT_NE(error(a).find("expected ID:FILE"), std::string::npos);
  a.insert = {scene.vehicles[0].id + ":" + dir + "/boxes.json"};
  EXPECT_NE(error(a).find("exactly one instance, found 5"), std::string::npos);
  a = args;
  a.remove = {"zzz"};
  EXPECT_NE(error(a).find("--remove zzz: no instance"), std::string::npos);
  a = args;
  a.edit_mode = "2.5d";
  EXPECT_NE(error(a).find("not one of 2d, 3d"), std::string::npos);
}

}  // namespace
}  // namespace geodrive

namespace geodrive {
namespace {

TEST(DynamicEdit, RenderCommandAppliesEditsAndRecordsThem) {
  ASSERT_TRUE(std::ifstream(test::GeodriveBinary()).good())
      << test::GeodriveBinary() << " not built";
  const Scene& scene = TestScene();
  const std::string dir = test::MakeTempDir("edit_cli_run");
  WritePly(dir + "/cloud.ply", scene.cloud);
  Trajectory traj;
  for (size_t t = 0; t < scene.cam_from_world.size(); ++t)
    traj.Add(0.1 * t, scene.cam_from_world[t].Inverse());
  TrajectoryFileInfo info;
  info.camera = scene.camera;
  WriteTrajectoryJson(dir + "/traj.json", traj, info);
  WriteBoxesJson(dir + "/boxes.json", scene.boxes);
  BoxSequences copy = scene.boxes;
  copy.instances.resize(1);
  copy.instances[0].id = "v0-copy";
  for (BoxFrame& f : copy.instances[0].frames) {
    f.box_2d.reset();
    f.box_3d->center.y() = -1.0;
  }
  WriteBoxesJson(dir + "/copy.json", copy);
  const std::string base = test::GeodriveBinary() + " render --cloud " + dir +
                           "/cloud.ply --trajectory " + dir +
                           "/traj.json --size 288x512 --no-video --boxes " +
                           dir + "/boxes.json ";
  std::string out;
  ASSERT_EQ(test::RunCommand(base + "--remove v1-left --insert v0-close:" +
                                 dir + "/copy.json --out " + dir + "/out",
                             &out),
            0)
      << out;
  std::ifstream in(dir + "/out/render.json");
  const std::string js((std::istreambuf_iterator<char>(in)),
                       std::istreambuf_iterator<char>());
  EXPECT_NE(js.find("\"dynamic_edit\""), std::string::npos) << js;
  EXPECT_NE(js.find("\"kind\": \"remove\""), std::string::npos) << js;
  EXPECT_NE(js.find("\"kind\": \"insert\""), std::string::npos) << js;
  // Bad input: exit 2 and one line naming the problem.
  EXPECT_EQ(
      test::RunCommand(base + "--remove nope --out " + dir + "/bad", &out), 2)
      << out;
  EXPECT_NE(out.find("no instance 'nope'"), std::string::npos) << out;
}

}  // namespace
}  // namespace geodrive
