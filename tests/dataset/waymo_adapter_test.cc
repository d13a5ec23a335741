// The Waymo v1 DriveDataset adapter (dataset/waymo_adapter.cc): the shared
// real frame opens as a one-scene dataset whose clip equals what
// ReadWaymoFrames gives; a multi-frame segment written here gives the
// expected clips, ids and frame order; `geodrive clips --dataset waymo` lists
// them.

#include <gtest/gtest.h>
#include <zlib.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "dataset/drive_dataset.h"
#include "dataset/waymo/tfrecord.h"
#include "dataset/waymo/waymo_frame.h"
#include "dataset/waymo/waymo_range_image.h"
#include "geometry/image_io.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "waymo_open_dataset/dataset.pb.h"

namespace geodrive {
// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder.
namespace waymo_adapter_test {

using ::testing::HasSubstr;
namespace wod = ::waymo::open_dataset;

void SetTransform(const Eigen::Matrix4d& m, wod::Transform* t) {
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) t->add_transform(m(r, c));
}

// Frame `i` of a small segment: FRONT and FRONT_LEFT 64x48 cameras (FRONT
// with distortion), the vehicle 1 m further along +x per frame, one car.
// zlib of a MatrixFloat [2, 4, 4] whose ranges are 5, 6, ... with one empty
// pixel (range 0).
std::string SmallRangeImage() {
  wod::MatrixFloat m;
  for (int d : {2, 4, 4}) m.mutable_shape()->add_dims(d);
  for (int i = 0; i < 8; ++i)
    for (float v : {i == 5 ? 0.0f : 5.0f + i, 0.5f, 0.1f, -1.0f}) m.add_data(v);
  const std::string bytes = m.SerializeAsString();
  uLongf size = compressBound(bytes.size());
  std::string out(size, '\0');
  compress2(reinterpret_cast<Bytef*>(out.data()), &size,
            reinterpret_cast<const Bytef*>(bytes.data()), bytes.size(), 6);
  out.resize(size);
  return out;
}

std::string SegmentFrame(const std::string& context,
                         int i,
                         bool lidar = false) {
  wod::Frame frame;
  frame.mutable_context()->set_name(context);
  frame.set_timestamp_micros(1000000 + 100000 * i);
  Eigen::Matrix4d world_from_vehicle = Eigen::Matrix4d::Identity();
  world_from_vehicle(0, 3) = i;
  SetTransform(world_from_vehicle, frame.mutable_pose());
  for (auto name : {wod::CameraName::FRONT, wod::CameraName::FRONT_LEFT}) {
    wod::CameraCalibration* cal =
        frame.mutable_context()->add_camera_calibrations();
    cal->set_name(name);
    const double k1 = name == wod::CameraName::FRONT ? -0.05 : 0.0;
    for (double v : {50.0, 51.0, 32.0, 24.0, k1, 0.0, 0.0, 0.0, 0.0})
      cal->add_intrinsic(v);
    Eigen::Matrix4d extrinsic = Eigen::Matrix4d::Identity();
    extrinsic(2, 3) = 1.5;
    SetTransform(extrinsic, cal->mutable_extrinsic());
    cal->set_width(64);
    cal->set_height(48);
    cv::Mat rgb(48, 64, CV_8UC3, cv::Scalar(10 * i, 120, 200));
    const std::vector<uint8_t> jpeg = EncodeJpegRgb(rgb, 90);
    wod::CameraImage* image = frame.add_images();
    image->set_name(name);
    image->set_image(std::string(jpeg.begin(), jpeg.end()));
  }
  if (lidar) {
    wod::LaserCalibration* cal =
        frame.mutable_context()->add_laser_calibrations();
    cal->set_name(wod::LaserName::TOP);
    cal->add_beam_inclinations(-0.3);
    cal->add_beam_inclinations(0.04);
    SetTransform(Eigen::Matrix4d::Identity(), cal->mutable_extrinsic());
    wod::Laser* laser = frame.add_lasers();
    laser->set_name(wod::LaserName::TOP);
    laser->mutable_ri_return1()->set_range_image_compressed(SmallRangeImage());
  }
  wod::Label* label = frame.add_laser_labels();
  label->set_id("car0");
  label->set_type(wod::Label::TYPE_VEHICLE);
  wod::Label::Box* box = label->mutable_box();
  box->set_center_x(10 - i);
  box->set_length(4.5);
  box->set_width(1.9);
  box->set_height(1.6);
  box->set_heading(0.2);
  std::string bytes;
  EXPECT_TRUE(frame.SerializeToString(&bytes));
  return bytes;
}

// A segment of `n` frames written out of time order (reversed).
std::string WriteSegment(const std::string& dir,
                         const std::string& context,
                         int n,
                         bool lidar = false) {
  std::vector<std::string> records;
  for (int i = n - 1; i >= 0; --i)
    records.push_back(SegmentFrame(context, i, lidar));
  const std::string path = dir + "/" + context + ".tfrecord";
  WriteTfRecordFile(path, records);
  return path;
}

DriveDatasetOptions WaymoOptions(const std::string& root) {
  DriveDatasetOptions o;
  o.format = DatasetFormat::kWaymo;
  o.root = root;
  o.channel = "FRONT";
  o.clip_frames = 3;
  o.clip_stride = 2;
  return o;
}

TEST(WaymoAdapter, FormatParsesAndIsDetected) {
  EXPECT_EQ(ParseDatasetFormat("waymo"), DatasetFormat::kWaymo);
  EXPECT_EQ(ToString(DatasetFormat::kWaymo), "waymo");
  const std::string dir = test::MakeTempDir("waymo_adapter_detect");
  EXPECT_EQ(DetectDatasetFormat(dir), DatasetFormat::kNuscenes);
  WriteSegment(dir, "seg", 2);
  EXPECT_EQ(DetectDatasetFormat(dir), DatasetFormat::kWaymo);
  EXPECT_EQ(DetectDatasetFormat(dir + "/seg.tfrecord"), DatasetFormat::kWaymo);
}

TEST(WaymoAdapter, SegmentGivesClipsInTimeOrder) {
  const std::string dir = test::MakeTempDir("waymo_adapter_segment");
  WriteSegment(dir, "segment_b.v2", 7);
  WriteSegment(dir, "segment_a", 4);
  DriveDatasetOptions options = WaymoOptions(dir);
  options.channel = "CAM_FRONT";  // read as FRONT
  const auto dataset = OpenDriveDataset(options);
  // 4 frames: starts 0; 7 frames: starts 0, 2, 4. Files in name order.
  EXPECT_EQ(dataset->ClipIds(), (std::vector<std::string>{
                                    "segment_a_0000", "segment_b_v2_0000",
                                    "segment_b_v2_0002", "segment_b_v2_0004"}));
  EXPECT_FALSE(dataset->HasLidar());
  EXPECT_THAT(dataset->Describe(),
              HasSubstr("no range images: LiDAR geometry unavailable"));
  const DriveClip clip = dataset->LoadClip("segment_b_v2_0002");
  EXPECT_EQ(clip.scene_name, "segment_b.v2");
  EXPECT_EQ(clip.channel, "FRONT");
  ASSERT_EQ(clip.num_frames(), 3);
  for (int k = 0; k < 3; ++k) {
    const DriveFrame& f = clip.frames[k];
    EXPECT_EQ(f.timestamp_us, 1000000 + 100000 * (2 + k));
    // Records were written reversed: frame 2 + k is record 6 - (2 + k).
    EXPECT_EQ(f.relative_path,
              "segment_b.v2.tfrecord#" + std::to_string(4 - k) + ":FRONT");
    // OpenCV camera 1.5 m up looking along +x, vehicle at x = 2 + k.
    const Eigen::Vector3d c = f.world_from_cam.translation;
    EXPECT_NEAR((c - Eigen::Vector3d(2 + k, 0, 1.5)).norm(), 0, 1e-12);
    EXPECT_NEAR((f.world_from_cam.rotation * Eigen::Vector3d::UnitZ() -
                 Eigen::Vector3d::UnitX())
                    .norm(),
                0, 1e-12);
    ASSERT_EQ(f.boxes.size(), 1u);
    EXPECT_EQ(f.boxes[0].instance_id, "car0");
    EXPECT_EQ(f.boxes[0].category, "vehicle.car");
    EXPECT_NEAR(f.boxes[0].box.center.x(), 10.0, 1e-12);  // static in world
    EXPECT_DOUBLE_EQ(f.camera.fx, 50.0);
    // The image resolves through the readers: FRONT is undistorted (PNG).
    const ImageFile image = ReadImageFile(f.image_path);
    EXPECT_FALSE(ReadImageHeader(image).jpeg);
    const cv::Mat rgb = ReadImageRgb(f.image_path);
    EXPECT_EQ(rgb.cols, 64);
    EXPECT_EQ(rgb.rows, 48);
  }
  EXPECT_THROW(dataset->LoadClip("segment_b_v2_0001"), InputError);
}

TEST(WaymoAdapter, RangeImagesGiveOneSweepPerFrame) {
  const std::string dir = test::MakeTempDir("waymo_adapter_lidar");
  const std::string path = WriteSegment(dir, "seg", 3, /*lidar=*/true);
  const auto dataset = OpenDriveDataset(WaymoOptions(dir));
  EXPECT_TRUE(dataset->HasLidar());
  EXPECT_THAT(dataset->Describe(), ::testing::Not(HasSubstr("no range")));
  const DriveClip clip = dataset->LoadClip("seg_0000");
  ASSERT_NE(clip.lidar, nullptr);
  ASSERT_EQ(clip.lidar->Sweeps().size(), 3u);
  const std::vector<WaymoFrame> frames = ReadWaymoFrames(path);
  for (int k = 0; k < 3; ++k) {
    ASSERT_EQ(clip.frames[k].keyframe_sweep, std::optional<size_t>(k));
    const LidarSweepInfo& sweep = clip.lidar->Sweeps()[k];
    EXPECT_EQ(sweep.timestamp_us, clip.frames[k].timestamp_us);
    EXPECT_NEAR(sweep.WorldFromSensor().translation.x(), k, 1e-12);
    // Frame k is record 2 - k (written reversed).
    const WaymoFrame& frame = frames[2 - k];
    const std::vector<Eigen::Vector3d> want = WaymoRangeImagePoints(
        DecodeWaymoRangeImage(frame.lasers[0].return1, 4, path, 2 - k, "TOP"),
        frame.laser_calibrations[0]);
    const PointCloud cloud = clip.lidar->Load(k);
    ASSERT_EQ(cloud.positions.size(), want.size());
    EXPECT_EQ(want.size(), 7u);  // 8 pixels, one empty
    for (size_t p = 0; p < want.size(); ++p)
      EXPECT_LE((cloud.positions[p].cast<double>() - want[p]).norm(), 1e-5);
    EXPECT_EQ(clip.lidar->Boxes(k).size(), 1u);
  }
}

TEST(WaymoAdapter, RigCarriesEveryCamera) {
  const std::string dir = test::MakeTempDir("waymo_adapter_rig");
  WriteSegment(dir, "seg", 3);
  DriveDatasetOptions options = WaymoOptions(dir);
  options.cameras = {"all"};
  const DriveClip clip = OpenDriveDataset(options)->LoadClip("seg_0000");
  ASSERT_EQ(clip.num_views(), 2);
  EXPECT_EQ(clip.rig[1].channel, "FRONT_LEFT");
  // FRONT_LEFT has no distortion: the JPEG as stored.
  EXPECT_TRUE(
      ReadImageHeader(ReadImageFile(clip.rig[1].frames[0].image_path)).jpeg);
}

TEST(WaymoAdapter, RealFrameEqualsTheReader) {
  const std::string path =
      test::RealDataPath("waymo_one_frame/pvps_data_one_frame.tfrecord");
  ASSERT_TRUE(std::filesystem::exists(path)) << "no real data at " << path;
  const std::vector<WaymoFrame> frames = ReadWaymoFrames(path);
  ASSERT_EQ(frames.size(), 1u);
  const WaymoFrame& frame = frames[0];
  DriveDatasetOptions options = WaymoOptions(path);
  options.clip_frames = 2;  // one frame gives no two-frame clip
  EXPECT_TRUE(OpenDriveDataset(options)->ClipIds().empty());
  // The frame is read as a rig of two-frame clips of a segment holding the
  // real record twice (timestamps apart), so that the clip's second frame
  // is checked too (WaymoPairs.RealFrameBuildsAOneFramePair builds the file
  // as it is, a one-frame clip).
  const std::string dir = test::MakeTempDir("waymo_adapter_real");
  wod::Frame proto;
  ASSERT_TRUE(proto.ParseFromString(ReadTfRecords(path)[0]));
  const std::string first = proto.SerializeAsString();
  proto.set_timestamp_micros(proto.timestamp_micros() + 100000);
  WriteTfRecordFile(dir + "/real.tfrecord", {first, proto.SerializeAsString()});
  options.root = dir;
  options.cameras = {"all"};
  const auto dataset = OpenDriveDataset(options);
  ASSERT_EQ(dataset->ClipIds().size(), 1u);
  const DriveClip clip = dataset->LoadClip(dataset->ClipIds()[0]);
  EXPECT_EQ(clip.scene_name, frame.context_name);
  ASSERT_EQ(clip.num_views(), 5);
  const Rigid3d world_from_vehicle =
      Rigid3d::FromMatrix(frame.world_from_vehicle);
  for (const CameraStream& stream : clip.rig) {
    const DriveFrame& f = stream.frames[0];
    const WaymoCameraCalibration* cal = nullptr;
    for (const auto& c : frame.camera_calibrations)
      if (ToString(c.name) == stream.channel) cal = &c;
    ASSERT_NE(cal, nullptr) << stream.channel;
    // The camera at its own capture: the image's own vehicle pose.
    const WaymoCameraImage* image = nullptr;
    for (const auto& im : frame.images)
      if (ToString(im.name) == stream.channel) image = &im;
    ASSERT_NE(image, nullptr) << stream.channel;
    ASSERT_TRUE(image->has_pose) << stream.channel;
    const Eigen::Matrix4d expected =
        image->world_from_vehicle * cal->vehicle_from_camera;
    EXPECT_LE((f.world_from_cam.ToMatrix() - expected).cwiseAbs().maxCoeff(),
              1e-9)
        << stream.channel;
    EXPECT_NEAR(f.camera.fx, cal->intrinsics.f_u, 1e-9);
    EXPECT_NEAR(f.camera.fy, cal->intrinsics.f_v, 1e-9);
    EXPECT_NEAR(f.camera.cx, cal->intrinsics.c_u, 1e-9);
    EXPECT_NEAR(f.camera.cy, cal->intrinsics.c_v, 1e-9);
    EXPECT_EQ(f.camera.width, cal->width);
    EXPECT_EQ(f.camera.height, cal->height);
    EXPECT_EQ(f.timestamp_us, std::llround(image->pose_timestamp * 1e6));
    // Not the frame's: the camera fires after the frame time.
    EXPECT_NE(f.timestamp_us, frame.timestamp_micros);
    ASSERT_EQ(f.boxes.size(), frame.laser_labels.size());
    for (size_t b = 0; b < f.boxes.size(); ++b) {
      const WaymoBox3d& w = frame.laser_labels[b];
      EXPECT_EQ(f.boxes[b].instance_id, w.id);
      const Eigen::Vector3d center = world_from_vehicle * w.center;
      EXPECT_LE((f.boxes[b].box.center - center).norm(), 1e-9);
      // The box's corners equal the reader's corners moved to the world.
      const std::vector<Eigen::Vector3d> corners = WaymoBoxCorners(w);
      const Rigid3d world_from_box = f.boxes[b].box.WorldFromBox();
      const Eigen::Vector3d half = f.boxes[b].box.HalfExtents();
      double worst = 0;
      for (const Eigen::Vector3d& c : corners) {
        const Eigen::Vector3d local =
            world_from_box.Inverse() * (world_from_vehicle * c);
        worst =
            std::max(worst, (local.cwiseAbs() - half).cwiseAbs().maxCoeff());
      }
      EXPECT_LE(worst, 1e-9) << w.id;
    }
  }
  // Each image decodes (undistorted) at its calibrated size, and its pixel
  // (u, v) is the stored JPEG sampled bilinearly where ProjectWaymoCamera
  // puts the ray of the pinhole pixel (u, v).
  for (const CameraStream& stream : clip.rig) {
    const DriveFrame& f = stream.frames[0];
    ReadImageRgb(f.image_path);  // the first read makes the remap tables
    const auto t0 = std::chrono::steady_clock::now();
    const cv::Mat rgb = ReadImageRgb(f.image_path);
    const double read_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
            .count();
    ASSERT_EQ(rgb.cols, f.camera.width);
    ASSERT_EQ(rgb.rows, f.camera.height);
    const WaymoCameraCalibration* cal = nullptr;
    const WaymoCameraImage* stored = nullptr;
    for (const auto& c : frame.camera_calibrations)
      if (ToString(c.name) == stream.channel) cal = &c;
    for (const auto& i : frame.images)
      if (ToString(i.name) == stream.channel) stored = &i;
    const cv::Mat jpeg = DecodeImageRgb(ImageFile{
        stream.channel,
        std::vector<uint8_t>(stored->jpeg.begin(), stored->jpeg.end())});
    double worst = 0;
    int black = 0;
    for (int v = 0; v < rgb.rows; ++v)
      for (int u = 0; u < rgb.cols; ++u)
        if (rgb.at<cv::Vec3b>(v, u) == cv::Vec3b(0, 0, 0)) ++black;
    for (int v = 40; v < rgb.rows - 40; v += 37) {
      for (int u = 40; u < rgb.cols - 40; u += 41) {
        Eigen::Vector2d px;
        const Eigen::Vector3d ray((u - f.camera.cx) / f.camera.fx,
                                  (v - f.camera.cy) / f.camera.fy, 1.0);
        if (ProjectWaymoCamera(*cal, ray, &px) != WaymoProjection::kValid)
          continue;
        if (px.x() < 1 || px.y() < 1 || px.x() > jpeg.cols - 2 ||
            px.y() > jpeg.rows - 2)
          continue;
        cv::Mat sample;
        cv::getRectSubPix(
            jpeg, cv::Size(1, 1),
            cv::Point2f(static_cast<float>(px.x()), static_cast<float>(px.y())),
            sample);
        const cv::Vec3b want = sample.at<cv::Vec3b>(0, 0);
        const cv::Vec3b got = rgb.at<cv::Vec3b>(v, u);
        for (int ch = 0; ch < 3; ++ch)
          worst = std::max(worst, std::abs(double(want[ch]) - got[ch]));
      }
    }
    std::printf(
        "%s: read and undistorted in %.3f s, %.3f%% black pixels, max %.0f "
        "levels from the stored JPEG at ProjectWaymoCamera's pixel\n",
        stream.channel.c_str(), read_s, 100.0 * black / (rgb.rows * rgb.cols),
        worst);
    // cv::remap interpolates at 1/32 pixel: a few levels on sharp edges.
    EXPECT_LE(worst, 4.0) << stream.channel;
  }
}

TEST(WaymoAdapter, ClipsCommandListsTheClips) {
  ASSERT_TRUE(std::filesystem::exists(test::GeodriveBinary()))
      << test::GeodriveBinary() << " not built";
  const std::string dir = test::MakeTempDir("waymo_adapter_cli");
  WriteSegment(dir, "seg", 5);
  std::string output;
  const int rc = test::RunCommand(
      test::GeodriveBinary() + " clips --dataset waymo --dataroot " + dir +
          " --out " + dir + "/out --clip-frames 3 --stride 2 2>&1",
      &output);
  ASSERT_EQ(rc, 0) << output;
  EXPECT_THAT(output, HasSubstr("2 clip(s) written"));
  const std::string index = test::ReadFile(dir + "/out/clips.jsonl");
  EXPECT_THAT(index, HasSubstr("seg_0000"));
  EXPECT_THAT(index, HasSubstr("seg_0002"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/out/seg_0002/images/00002.jpg"));
}

}  // namespace waymo_adapter_test
}  // namespace geodrive
