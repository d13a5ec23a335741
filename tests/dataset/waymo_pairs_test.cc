// Pairs from Waymo segments, end to end: `synth --format waymo` segments
// through the Waymo DriveDataset and build-dataset (--geometry lidar, the TOP
// range images), against the synthetic world's truth: the pair's boxes equal
// the world's vehicles, its condition (our camera model and the Waymo ->
// OpenCV camera axes) lands on the world's own images, and the pair files
// validate against the same schemas as nuScenes pairs.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <opencv2/imgcodecs.hpp>

#include "dataset/build_dataset.h"
#include "dataset/drive_dataset.h"
#include "dataset/pairs.h"
#include "dataset/synthetic/synthetic_waymo.h"
#include "dataset/synthetic/synthetic_world.h"
#include "dataset/waymo/waymo_frame.h"
#include "geometry/image_io.h"
#include "render/boxes.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace waymo_pairs_test {
namespace {

namespace fs = std::filesystem;

SyntheticWaymoOptions SegmentOptions() {
  SyntheticWaymoOptions o;
  o.num_scenes = 1;
  o.seed = 7;
  o.image_width = 480;
  o.image_height = 320;
  o.scene_duration_s = 2.6;  // 26 frames at 10 Hz: one 25-frame clip
  o.lidar_columns = 1325;
  return o;
}

// One segment and its pair, built once for all the test processes.
struct Built {
  std::string out, pair_dir;
  PairMeta meta;
};
const Built& BuiltPair() {
  static const Built built = [] {
    const std::string dir =
        test::SharedFixtureDir("waymo_pairs", [](const std::string& root) {
          WriteSyntheticWaymo(SegmentOptions(), root + "/segments");
          BuildDatasetOptions b;
          b.dataset = DatasetFormat::kWaymo;
          b.dataroot = root + "/segments";
          b.out = root + "/out";
          b.geometry = "lidar";
          b.width = 480;
          b.height = 320;
          b.threads = 1;
          const BuildDatasetSummary s = BuildDataset(b);
          EXPECT_EQ(s.built, 1);
        });
    Built out;
    out.out = dir + "/out";
    const std::vector<ManifestEntry> entries =
        ReadManifest(out.out + "/manifest.jsonl");
    EXPECT_EQ(entries.size(), 1u);
    out.pair_dir = out.out + "/" + entries.at(0).pair_dir;
    out.meta = ReadPairMeta(out.pair_dir);
    return out;
  }();
  return built;
}

// The FRONT camera of the rig and its pose in the world at frame i of the
// clip (its own trigger time, as the segment stores the image's pose).
Rigid3d WorldFromFront(const SyntheticWorld& world,
                       const SyntheticWaymoCamera& front,
                       int frame) {
  const double t = SyntheticWaymoFrameSeconds(frame) + front.time_offset_s;
  return world.GlobalFromEgo(t) * front.ego_from_camera;
}

// Every box of the pair (camera 0's frame) equals the world's vehicle at the
// frame's time, moved into the world's FRONT camera at frame 0.
TEST(WaymoPairs, BoxesEqualTheSyntheticTruth) {
  const Built& b = BuiltPair();
  const SyntheticWaymoOptions o = SegmentOptions();
  const SyntheticWorld world(SyntheticWaymoWorldOptions(o, 0));
  const SyntheticWaymoCamera front = SyntheticWaymoRig(o).at(0);
  ASSERT_EQ(front.name, WaymoCameraName::kFront);
  const Rigid3d cam0_from_world = WorldFromFront(world, front, 0).Inverse();
  const BoxSequences boxes = ReadBoxesJson(b.pair_dir + "/boxes.json");
  ASSERT_FALSE(boxes.instances.empty());
  std::map<std::string, int> id_of;
  for (int v = 0; v < world.NumVehicles(); ++v)
    id_of[SyntheticWaymoLabelId(v)] = v;
  int compared = 0;
  double worst_m = 0, worst_deg = 0, worst_size = 0;
  for (const BoxSequence& seq : boxes.instances) {
    ASSERT_TRUE(id_of.count(seq.id)) << seq.id;
    EXPECT_EQ(seq.category, "vehicle.car");
    for (const BoxFrame& f : seq.frames) {
      if (!f.box_3d) continue;
      const VehicleBox truth =
          world.Vehicle(id_of[seq.id], SyntheticWaymoFrameSeconds(f.frame));
      const Eigen::Vector3d center = cam0_from_world * truth.center;
      const Eigen::Quaterniond rotation =
          cam0_from_world.rotation * truth.rotation;
      worst_m = std::max(worst_m, (f.box_3d->center - center).norm());
      worst_deg = std::max(
          worst_deg, f.box_3d->rotation.angularDistance(rotation) * 180 / M_PI);
      worst_size = std::max(
          worst_size, (f.box_3d->size - truth.size_wlh).cwiseAbs().maxCoeff());
      ++compared;
    }
  }
  std::cout << compared << " boxes: centre within " << worst_m
            << " m, rotation within " << worst_deg << " deg, size within "
            << worst_size << " m\n";
  EXPECT_GT(compared, 25);
  EXPECT_LE(worst_m, 1e-3);
  EXPECT_LE(worst_deg, 0.01);
  EXPECT_LE(worst_size, 1e-3);
}

// The condition, rendered with our camera from the TOP range images, against
// the world's own images (the pair's ground truth): the Waymo camera axes
// converted to OpenCV's and each camera at its own capture put the points on
// their pixels. A wrong axis convention or pose draws nothing or the wrong
// surfaces (PSNR near 10 dB).
TEST(WaymoPairs, ConditionLandsOnTheWorldsOwnImages) {
  const Built& b = BuiltPair();
  const PairQuality& q = b.meta.quality;
  ASSERT_EQ(q.coverage.size(), 25u);
  ASSERT_TRUE(q.psnr_static.at(0).has_value());
  double sum = 0;
  int n = 0;
  for (const auto& p : q.psnr_static)
    if (p) sum += *p, ++n;
  std::cout << "frame 0: coverage " << q.coverage[0] << ", static-region PSNR "
            << *q.psnr_static[0] << " dB; clip mean PSNR " << sum / n
            << " dB over " << n << " frames\n";
  EXPECT_GE(q.coverage[0], 0.35);
  EXPECT_GE(*q.psnr_static[0], 22.0);
  EXPECT_GE(sum / n, 20.0);
  EXPECT_EQ(b.meta.intrinsics.width, 480);
  EXPECT_EQ(b.meta.pose_units, "metres");
}

// meta.json, boxes.json and the manifest line validate against the schemas
// the nuScenes pairs are checked with.
TEST(WaymoPairs, PairFilesValidateAgainstTheSchemas) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("jsonschema");
  const Built& b = BuiltPair();
  const std::string py = std::string(test::kDebianPython) +
                         " " GEODRIVE_SOURCE_DIR
                         "/tests/dataset/validate_json.py ";
  const std::string schemas = GEODRIVE_SOURCE_DIR "/data_schema/";
  std::string out;
  EXPECT_EQ(test::RunCommand(py + schemas + "pair_meta.schema.json " +
                                 b.pair_dir + "/meta.json",
                             &out),
            0)
      << out;
  EXPECT_EQ(test::RunCommand(py + schemas + "boxes.schema.json " + b.pair_dir +
                                 "/boxes.json",
                             &out),
            0)
      << out;
  EXPECT_EQ(test::RunCommand(py + "--jsonl " + schemas +
                                 "manifest_line.schema.json " + b.out +
                                 "/manifest.jsonl",
                             &out),
            0)
      << out;
}

// The same segment with --geometry lidar-dense: the TOP range image's frame-0
// returns completed over the FRONT camera's LiDAR-supported area, checked on
// the returns held out of the completion.
TEST(WaymoPairs, LidarDenseCompletesTheSupportedArea) {
  const std::string segments =
      fs::path(BuiltPair().out).parent_path().string() + "/segments";
  BuildDatasetOptions b;
  b.dataset = DatasetFormat::kWaymo;
  b.dataroot = segments;
  b.out = test::MakeTempDir("waymo_pairs_dense");
  b.geometry = "lidar-dense";
  b.width = 480;
  b.height = 320;
  b.quiet = true;
  ASSERT_EQ(BuildDataset(b).built, 1)
      << test::ReadFile(b.out + "/failures.jsonl");
  const std::vector<ManifestEntry> entries =
      ReadManifest(b.out + "/manifest.jsonl");
  ASSERT_EQ(entries.size(), 1u);
  const PairQuality q = ReadPairMeta(b.out + "/" + entries[0].pair_dir).quality;
  ASSERT_TRUE(q.supported_fraction && q.coverage_of_supported &&
              q.completion_holdout);
  ASSERT_TRUE(q.psnr_static.at(0).has_value());
  std::printf(
      "waymo lidar-dense: LiDAR supports %.3f of the image, %.3f of it "
      "completed; frame-0 coverage %.3f, static PSNR %.1f dB; held-out "
      "returns within 5 %%: %.3f (MAE %.2f m)\n",
      *q.supported_fraction, *q.coverage_of_supported, q.coverage.at(0),
      *q.psnr_static[0], q.completion_holdout->within_5_percent,
      q.completion_holdout->mae_m);
  // The section's requirement for nuScenes: >= 90 % of the supported area.
  EXPECT_GE(*q.coverage_of_supported, 0.9);
  // The TOP LiDAR reaches the lower half of the 480x320 FRONT view (measured
  // 0.49 at 720x480): the supported area is a real part of the image.
  EXPECT_GT(*q.supported_fraction, 0.3);
  // Measured 0.986 of held-out returns within 5 % on the synthetic world.
  EXPECT_GE(q.completion_holdout->within_5_percent, 0.95);
}

// The real one-frame file (no range images: no LiDAR geometry) as a one-frame
// pair. Its geometry is a stated one, written as a generic npz: the FRONT
// image itself at 480x320 on a fronto-parallel plane 20 m ahead, metric, at
// the camera's own pose. Rendered back at that pose the condition is the
// image: what this checks is the real file's path through the builder
// (calibration, image decode and resize, pixel convention, the laser labels
// as boxes, the one-frame clip), and the pair files validate against the
// nuScenes pairs' schemas.
TEST(WaymoPairs, RealFrameBuildsAOneFramePair) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  GEODRIVE_REQUIRE_PYTHON_MODULE("jsonschema");
  const std::string root = test::RealDataPath("waymo_one_frame");
  const std::string record = root + "/pvps_data_one_frame.tfrecord";
  ASSERT_TRUE(fs::exists(record)) << "real data missing: " << record;
  DriveDatasetOptions d;
  d.format = DatasetFormat::kWaymo;
  d.root = root;
  d.clip_frames = 1;
  const auto dataset = OpenDriveDataset(d);
  ASSERT_EQ(dataset->ClipIds().size(), 1u);
  const std::string clip_id = dataset->ClipIds()[0];
  const DriveClip clip = dataset->LoadClip(clip_id);
  ASSERT_EQ(clip.num_frames(), 1);
  const PinholeCamera& k = clip.frames[0].camera;
  ASSERT_EQ(k.width, 1920);
  ASSERT_EQ(k.height, 1280);

  const std::string dir = test::MakeTempDir("waymo_real_pair");
  // The frame as the pair's GT reads it: undistorted to the pinhole camera.
  const cv::Mat image = ReadImageRgb(clip.frames[0].image_path);
  ASSERT_EQ(image.cols, 1920);
  const std::vector<uint8_t> png = EncodePngImage(image);
  test::WriteFile(dir + "/front.png", std::string(png.begin(), png.end()));
  const std::vector<WaymoFrame> frames = ReadWaymoFrames(record);
  // K at 480x320 (a quarter: integer-index centres, c' = (c + 0.5) s - 0.5).
  const double s = 0.25;
  char k_text[160];
  std::snprintf(k_text, sizeof(k_text), "[[%.9f,0,%.9f],[0,%.9f,%.9f],[0,0,1]]",
                k.fx * s, (k.cx + 0.5) * s - 0.5, k.fy * s,
                (k.cy + 0.5) * s - 0.5);
  const std::string npz = dir + "/geometry/" + clip_id + "/scene.npz";
  fs::create_directories(fs::path(npz).parent_path());
  std::string log;
  ASSERT_EQ(
      test::RunCommand(
          std::string(test::kDebianPython) +
              " -c \"import numpy as np, cv2; "
              "img = cv2.resize(cv2.imread('" +
              dir +
              "/front.png')[:, :, ::-1], "
              "(480, 320), interpolation=cv2.INTER_AREA); "
              "np.savez('" +
              npz +
              "', depth=np.full((1, 320, 480), 20, np.float32), "
              "intrinsics=np.array(" +
              k_text +
              ", np.float32), "
              "cam_c2w=np.eye(4)[None], images=img[None], units='metres')\"",
          &log),
      0)
      << log;

  BuildDatasetOptions b;
  b.dataset = DatasetFormat::kWaymo;
  b.dataroot = root;
  b.monst3r_root = dir + "/geometry";
  b.geometry = "npz";
  b.clip_frames = 1;
  b.out = dir + "/out";
  b.quiet = true;
  const BuildDatasetSummary summary = BuildDataset(b);
  ASSERT_EQ(summary.built, 1) << test::ReadFile(b.out + "/failures.jsonl");
  // The default geometry needs the LiDAR the file does not have: the clip
  // fails with one line naming the clip and the way out.
  BuildDatasetOptions no_lidar = b;
  no_lidar.geometry = "lidar";
  no_lidar.monst3r_root.clear();
  no_lidar.out = dir + "/out_lidar";
  EXPECT_EQ(BuildDataset(no_lidar).failed, 1);
  const std::string failure = test::ReadFile(no_lidar.out + "/failures.jsonl");
  EXPECT_NE(failure.find(clip_id + ": no LiDAR (nuScenes LIDAR_TOP sweeps, "
                                   "Waymo range images): use a "
                                   "reconstruction"),
            std::string::npos)
      << failure;

  const std::string pair = b.out + "/pairs/" + clip_id;
  const PairMeta meta = ReadPairMeta(pair);
  EXPECT_EQ(meta.frames.size(), 1u);
  ASSERT_EQ(meta.quality.coverage.size(), 1u);
  ASSERT_TRUE(meta.quality.psnr_static.at(0).has_value());
  std::printf("real Waymo frame, one-frame pair: coverage %.4f, PSNR %.2f dB\n",
              meta.quality.coverage[0], *meta.quality.psnr_static[0]);
  // 480x320 points splatted one output pixel each at 720x480 (1.5x): 8 of
  // every 9 output pixels are drawn.
  EXPECT_NEAR(meta.quality.coverage[0], 8.0 / 9.0, 1e-3);
  // The image drawn back over itself: measured 29.3 dB (the 480x320 copy,
  // upsampled by the splats, against the 720x480 frame). The raw JPEG,
  // still distorted, gives 25.3 dB.
  EXPECT_GT(*meta.quality.psnr_static[0], 27.0);
  // The pair's boxes are the frame's vehicle and cyclist laser labels (the
  // builder's vehicle boxes), one instance each, in the one frame.
  int vehicles = 0;
  for (const WaymoBox3d& box : frames[0].laser_labels)
    vehicles += box.type == WaymoObjectType::kVehicle ||
                box.type == WaymoObjectType::kCyclist;
  const std::string boxes = test::ReadFile(pair + "/boxes.json");
  int instances = 0;
  for (size_t at = boxes.find("\"category\""); at != std::string::npos;
       at = boxes.find("\"category\"", at + 1))
    ++instances;
  std::printf("boxes: %d instances, %d vehicle and cyclist laser labels\n",
              instances, vehicles);
  EXPECT_GT(vehicles, 0);
  EXPECT_EQ(instances, vehicles);
  EXPECT_NE(boxes.find("\"num_frames\": 1"), std::string::npos);

  const std::string py = std::string(test::kDebianPython) +
                         " " GEODRIVE_SOURCE_DIR
                         "/tests/dataset/validate_json.py ";
  const std::string schemas = GEODRIVE_SOURCE_DIR "/data_schema/";
  EXPECT_EQ(
      test::RunCommand(
          py + schemas + "pair_meta.schema.json " + pair + "/meta.json", &log),
      0)
      << log;
  EXPECT_EQ(
      test::RunCommand(
          py + schemas + "boxes.schema.json " + pair + "/boxes.json", &log),
      0)
      << log;
  EXPECT_EQ(test::RunCommand(py + "--jsonl " + schemas +
                                 "manifest_line.schema.json " + b.out +
                                 "/manifest.jsonl",
                             &log),
            0)
      << log;
}

}  // namespace
}  // namespace waymo_pairs_test
}  // namespace geodrive
