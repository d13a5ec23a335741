// geodrive synth --format waymo: the synthetic world written as Waymo v1
// segments and read back with the Waymo reader, against the world's truth.

#include "dataset/synthetic/synthetic_waymo.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <set>

#include "dataset/waymo/waymo_frame.h"
#include "dataset/waymo/waymo_range_image.h"
#include "geometry/image_io.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace synthetic_waymo_test {
namespace {

SyntheticWaymoOptions SmallOptions() {
  SyntheticWaymoOptions o;
  o.num_scenes = 1;
  o.seed = 7;
  o.image_width = 96;
  o.image_height = 64;
  o.scene_duration_s = 1.0;
  o.lidar_columns = 720;
  return o;
}

// The small segment, written once for all the test processes.
struct Segment {
  std::string path;
  std::vector<WaymoFrame> frames;
};
const Segment& SmallSegment() {
  static const Segment segment = [] {
    const std::string dir =
        test::SharedFixtureDir("synthetic_waymo", [](const std::string& d) {
          const SyntheticWaymoSummary s =
              WriteSyntheticWaymo(SmallOptions(), d);
          test::WriteFile(d + "/segment_path.txt", s.files.at(0));
        });
    Segment out;
    out.path = test::ReadFile(dir + "/segment_path.txt");
    out.frames = ReadWaymoFrames(out.path);
    return out;
  }();
  return segment;
}

double MaxAbs(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b) {
  return (a - b).cwiseAbs().maxCoeff();
}

double AngleDiff(double a, double b) {
  return std::abs(std::remainder(a - b, 2 * M_PI));
}

TEST(SyntheticWaymo, WritesOneSegmentNamedLikeWaymos) {
  const SyntheticWaymoOptions o = SmallOptions();
  const Segment& s = SmallSegment();
  EXPECT_EQ(std::filesystem::path(s.path).filename().string(),
            "segment-synthetic_7_0_000_1000_with_camera_labels.tfrecord");
  ASSERT_EQ(static_cast<int>(s.frames.size()), SyntheticWaymoNumFrames(o));
  ASSERT_EQ(s.frames.size(), 10u);
  for (size_t i = 0; i < s.frames.size(); ++i) {
    const WaymoFrame& f = s.frames[i];
    EXPECT_EQ(f.context_name, SyntheticWaymoContextName(o, 0));
    EXPECT_EQ(f.timestamp_micros,
              SyntheticWaymoTimestampMicros(o, 0, static_cast<int>(i)));
    EXPECT_EQ(f.images.size(), 5u);
    EXPECT_EQ(f.camera_calibrations.size(), 5u);
    EXPECT_TRUE(f.has_range_images);
    EXPECT_EQ(f.projected_lidar_labels.size(), 5u);
    EXPECT_EQ(f.camera_labels.size(), 5u);
  }
}

TEST(SyntheticWaymo, PosesAndBoxesEqualTheWorldsTruth) {
  const SyntheticWaymoOptions o = SmallOptions();
  const SyntheticWorld world(SyntheticWaymoWorldOptions(o, 0));
  const std::vector<SyntheticWaymoCamera> rig = SyntheticWaymoRig(o);
  double pose_err = 0, center_err = 0, size_err = 0, heading_err = 0;
  std::map<std::string, int> frames_per_id;
  for (size_t i = 0; i < SmallSegment().frames.size(); ++i) {
    const WaymoFrame& f = SmallSegment().frames[i];
    const double t = SyntheticWaymoFrameSeconds(static_cast<int>(i));
    const Rigid3d global_from_vehicle = world.GlobalFromEgo(t);
    pose_err = std::max(
        pose_err, MaxAbs(f.world_from_vehicle, global_from_vehicle.ToMatrix()));
    for (const SyntheticWaymoCamera& cam : rig) {
      const WaymoCameraImage* image = f.Image(cam.name);
      ASSERT_NE(image, nullptr);
      ASSERT_TRUE(image->has_pose);
      pose_err = std::max(
          pose_err,
          MaxAbs(image->world_from_vehicle,
                 world.GlobalFromEgo(t + cam.time_offset_s).ToMatrix()));
    }
    const Rigid3d vehicle_from_global = global_from_vehicle.Inverse();
    int expected = 0;
    for (const VehicleBox& v : world.Vehicles(t)) {
      const Eigen::Vector3d c = vehicle_from_global * v.center;
      if (c.head<2>().norm() > 75.0) continue;
      ++expected;
      const std::string id = SyntheticWaymoLabelId(v.id);
      const auto it =
          std::find_if(f.laser_labels.begin(), f.laser_labels.end(),
                       [&](const WaymoBox3d& b) { return b.id == id; });
      ASSERT_NE(it, f.laser_labels.end()) << id << " at frame " << i;
      ++frames_per_id[id];
      EXPECT_EQ(it->type, WaymoObjectType::kVehicle);
      center_err = std::max(center_err, (it->center - c).norm());
      size_err = std::max({size_err, std::abs(it->width - v.size_wlh.x()),
                           std::abs(it->length - v.size_wlh.y()),
                           std::abs(it->height - v.size_wlh.z())});
      // The box's x axis in the vehicle frame.
      const Eigen::Vector3d x = (vehicle_from_global.rotation * v.rotation) *
                                Eigen::Vector3d::UnitX();
      heading_err = std::max(heading_err,
                             AngleDiff(it->heading, std::atan2(x.y(), x.x())));
    }
    EXPECT_EQ(static_cast<int>(f.laser_labels.size()), expected);
  }
  std::cout << "poses " << pose_err << ", box centres " << center_err
            << " m, sizes " << size_err << " m, headings "
            << heading_err * 180 / M_PI << " deg" << std::endl;
  EXPECT_LE(pose_err, 1e-9);
  EXPECT_LE(center_err, 1e-3);
  EXPECT_LE(size_err, 1e-3);
  EXPECT_LE(heading_err * 180 / M_PI, 0.01);
  // Ids are stable: the lead car is labelled in every frame.
  EXPECT_EQ(frames_per_id[SyntheticWaymoLabelId(0)],
            static_cast<int>(SmallSegment().frames.size()));
}

TEST(SyntheticWaymo, CamerasMatchTheRigAndProjectAsTheWorldsCameras) {
  const SyntheticWaymoOptions o = SmallOptions();
  const SyntheticWorld world(SyntheticWaymoWorldOptions(o, 0));
  double extrinsic_err = 0, pixel_err = 0;
  int projected = 0;
  for (size_t i = 0; i < SmallSegment().frames.size(); ++i) {
    const WaymoFrame& f = SmallSegment().frames[i];
    const double t = SyntheticWaymoFrameSeconds(static_cast<int>(i));
    for (const SyntheticWaymoCamera& cam : SyntheticWaymoRig(o)) {
      const WaymoCameraCalibration* calib = f.Calibration(cam.name);
      ASSERT_NE(calib, nullptr);
      extrinsic_err = std::max(
          extrinsic_err,
          MaxAbs(calib->vehicle_from_camera, cam.ego_from_camera.ToMatrix()));
      EXPECT_EQ(calib->width, cam.camera.width);
      EXPECT_EQ(calib->height, cam.camera.height);
      EXPECT_EQ(calib->intrinsics.f_u, cam.camera.fx);
      EXPECT_EQ(calib->intrinsics.f_v, cam.camera.fy);
      EXPECT_EQ(calib->intrinsics.c_u, cam.camera.cx);
      EXPECT_EQ(calib->intrinsics.c_v, cam.camera.cy);
      const WaymoIntrinsics& k = calib->intrinsics;
      EXPECT_EQ(k.k1 == 0 && k.k2 == 0 && k.p1 == 0 && k.p2 == 0 && k.k3 == 0,
                true);
      EXPECT_EQ(calib->rolling_shutter, WaymoRollingShutter::kGlobalShutter);
      const WaymoCameraImage* image = f.Image(cam.name);
      const cv::Mat rgb = DecodeImageRgb(ImageFile{
          ToString(cam.name),
          std::vector<uint8_t>(image->jpeg.begin(), image->jpeg.end())});
      EXPECT_EQ(rgb.cols, calib->width);
      EXPECT_EQ(rgb.rows, calib->height);
      // Each box corner: world point from the frame pose, into the camera
      // with the image's own pose and the calibration (Waymo's model) vs the
      // world's camera at the trigger time.
      const Rigid3d global_from_cam =
          world.GlobalFromEgo(t + cam.time_offset_s) * cam.ego_from_camera;
      const Eigen::Matrix4d camera_from_world =
          calib->vehicle_from_camera.inverse() *
          image->world_from_vehicle.inverse();
      for (const WaymoBox3d& box : f.laser_labels) {
        for (const Eigen::Vector3d& corner : WaymoBoxCorners(box)) {
          const Eigen::Vector4d world_point =
              f.world_from_vehicle * corner.homogeneous();
          const Eigen::Vector3d p = (camera_from_world * world_point).head<3>();
          Eigen::Vector2d px;
          if (ProjectWaymoCamera(*calib, p, &px) != WaymoProjection::kValid)
            continue;
          const Eigen::Vector3d q = global_from_cam.Inverse() *
                                    Eigen::Vector3d(world_point.head<3>());
          const Eigen::Vector2d truth = cam.camera.Project(q);
          if (!cam.camera.InImage(truth)) continue;
          pixel_err = std::max(pixel_err, (px - truth).norm());
          ++projected;
        }
      }
    }
  }
  std::cout << "extrinsics " << extrinsic_err << ", " << projected
            << " corners in the images, largest pixel difference " << pixel_err
            << " px" << std::endl;
  EXPECT_LE(extrinsic_err, 1e-12);
  EXPECT_GT(projected, 50);
  EXPECT_LE(pixel_err, 0.01);
}

// Each camera_labels box (the vehicle's visible pixels) lies inside its
// projected_lidar_labels box (the projected 3D box at the image's pose) up to
// the half pixel of the pixel edges and the vehicle's own motion between the
// frame time and the camera's trigger time.
TEST(SyntheticWaymo, CameraLabelsLieInsideTheProjectedBoxes) {
  double worst = 0;
  int pairs = 0;
  for (const WaymoFrame& f : SmallSegment().frames) {
    for (const WaymoCameraLabels& visible : f.camera_labels) {
      const WaymoCameraLabels* projected = f.ProjectedLidarLabels(visible.name);
      ASSERT_NE(projected, nullptr);
      for (const WaymoBox2d& v : visible.boxes) {
        const auto it =
            std::find_if(projected->boxes.begin(), projected->boxes.end(),
                         [&](const WaymoBox2d& p) { return p.id == v.id; });
        if (it == projected->boxes.end()) continue;  // a corner behind
        ++pairs;
        worst = std::max(
            {worst,
             (it->center_x - 0.5 * it->size_x) - (v.center_x - 0.5 * v.size_x),
             (v.center_x + 0.5 * v.size_x) - (it->center_x + 0.5 * it->size_x),
             (it->center_y - 0.5 * it->size_y) - (v.center_y - 0.5 * v.size_y),
             (v.center_y + 0.5 * v.size_y) -
                 (it->center_y + 0.5 * it->size_y)});
      }
    }
  }
  std::cout << pairs
            << " visible boxes, largest overhang beyond the projected box "
            << worst << " px" << std::endl;
  EXPECT_GT(pairs, 20);
  EXPECT_LE(worst, 1.0);
}

TEST(SyntheticWaymo, RangeImagePointsLieOnTheWorldsSurfaces) {
  const SyntheticWaymoOptions o = SmallOptions();
  const SyntheticWorld world(SyntheticWaymoWorldOptions(o, 0));
  std::vector<double> errors, errors_posed;
  for (size_t i = 0; i < SmallSegment().frames.size(); i += 3) {
    const WaymoFrame& f = SmallSegment().frames[i];
    const double t = SyntheticWaymoFrameSeconds(static_cast<int>(i));
    ASSERT_EQ(f.lasers.size(), 1u);
    ASSERT_EQ(f.laser_calibrations.size(), 1u);
    const WaymoRangeImage image = DecodeWaymoRangeImage(
        f.lasers[0].return1, 4, SmallSegment().path, 0, "laser TOP");
    ASSERT_EQ(image.height, 64);
    ASSERT_EQ(image.width, o.lidar_columns);
    const WaymoRangeImage pose = DecodeWaymoRangeImage(
        f.lasers[0].top_pose, 6, SmallSegment().path, 0, "laser TOP pose");
    const WaymoLaserCalibration& laser = f.laser_calibrations[0];
    const std::vector<Eigen::Vector3d> points =
        WaymoRangeImagePoints(image, laser);
    const std::vector<Eigen::Vector3d> posed =
        WaymoRangeImagePoints(image, laser, &pose, f.world_from_vehicle);
    ASSERT_EQ(points.size(), posed.size());
    ASSERT_GT(points.size(), 64u * 720 / 2);
    const Eigen::Vector3d origin =
        (f.world_from_vehicle * laser.vehicle_from_laser)
            .topRightCorner<3, 1>();
    for (size_t k = 0; k < points.size(); k += 5) {
      for (const auto& [set, out] : {std::make_pair(&points, &errors),
                                     std::make_pair(&posed, &errors_posed)}) {
        const Eigen::Vector3d w =
            (f.world_from_vehicle * (*set)[k].homogeneous()).head<3>();
        const Eigen::Vector3d d = w - origin;
        const RayHit hit = world.CastRay(origin, d, t);
        out->push_back(hit.range > 0 ? std::abs(hit.range - d.norm()) : 1e9);
      }
    }
  }
  for (std::vector<double>* e : {&errors, &errors_posed}) {
    std::sort(e->begin(), e->end());
    const double median = (*e)[e->size() / 2];
    const double p99 = (*e)[e->size() * 99 / 100];
    std::cout << (e == &errors ? "range image points" : "with the pixel poses")
              << ": " << e->size() << " checked, |range - true range| median "
              << median * 1e3 << " mm, 99% " << p99 * 1e3 << " mm, max "
              << e->back() * 1e3 << " mm" << std::endl;
    EXPECT_LE(median, 1e-4);
    EXPECT_LE(p99, 1e-3);
  }
}

TEST(SyntheticWaymo, SameOptionsGiveIdenticalBytes) {
  SyntheticWaymoOptions o = SmallOptions();
  o.scene_duration_s = 1.0;
  o.lidar_columns = 200;
  const std::string a = test::MakeTempDir("synthetic_waymo_a");
  const std::string b = test::MakeTempDir("synthetic_waymo_b");
  const SyntheticWaymoSummary sa = WriteSyntheticWaymo(o, a);
  const SyntheticWaymoSummary sb = WriteSyntheticWaymo(o, b);
  ASSERT_EQ(sa.files.size(), 1u);
  EXPECT_EQ(test::ReadFile(sa.files[0]), test::ReadFile(sb.files[0]));
  EXPECT_GT(sa.num_bytes, 0);
}

TEST(SyntheticWaymo, BadOptionsAreRefused) {
  SyntheticWaymoOptions o = SmallOptions();
  EXPECT_TRUE(o.Check());
  o.image_width = 4;
  EXPECT_FALSE(o.Check());
  EXPECT_THROW(WriteSyntheticWaymo(o, test::MakeTempDir("synthetic_waymo_bad")),
               InputError);
  o = SmallOptions();
  o.lidar_columns = 0;
  EXPECT_FALSE(o.Check());
  o = SmallOptions();
  o.scene_duration_s = 0.5;
  EXPECT_FALSE(o.Check());
}

}  // namespace
}  // namespace synthetic_waymo_test
}  // namespace geodrive
