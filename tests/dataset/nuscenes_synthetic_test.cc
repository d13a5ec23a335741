// The synthetic world (dataset/synthetic/synthetic_dataset.h) read back through
// the nuScenes reader: references, chains, rates and layout; 2D boxes from the
// reader's box projection against a brute-force ray-cast of the true vehicle
// pixels.

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/core.hpp>

#include "dataset/nuscenes.h"
#include "dataset/nuscenes_projection.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "dataset/synthetic/synthetic_world.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

struct SyntheticFixture {
  SyntheticDatasetOptions options;
  std::string root;
  SyntheticFixture() {
    options.num_scenes = 1;
    options.image_width = 320;
    options.image_height = 180;
    options.scene_duration_s = 4.0;
    options.lidar_azimuth_steps = 90;
    root = test::MakeTempDir("nusc_synthetic");
    WriteSyntheticDataset(options, root);
  }
};

const SyntheticFixture& Fixture() {
  static const SyntheticFixture* fixture = new SyntheticFixture();
  return *fixture;
}

Nuscenes Load() {
  NuscenesOptions options;
  options.dataroot = Fixture().root;
  options.version = Fixture().options.version;
  return Nuscenes(options);  // throws if any token reference does not resolve
}

TEST(NuscenesSynthetic, ChainsRatesAndLayout) {
  const Nuscenes nusc = Load();
  ASSERT_EQ(nusc.scenes().size(), 1u);
  const struct {
    const char* channel;
    double rate;
  } kRates[] = {{"CAM_FRONT", 12}, {"LIDAR_TOP", 20}};
  for (const auto& r : kRates) {
    const auto chain = nusc.Chain(0, r.channel);
    ASSERT_GT(chain.size(), 10u) << r.channel;
    int keyframes = 0;
    for (size_t i = 0; i < chain.size(); ++i) {
      const auto& sd = nusc.sample_data()[chain[i]];
      if (i > 0) {
        const double dt =
            sd.timestamp - nusc.sample_data()[chain[i - 1]].timestamp;
        EXPECT_NEAR(dt, 1e6 / r.rate, 1000.0) << r.channel << " " << i;
      }
      const std::string dir =
          std::string(sd.is_key_frame ? "samples/" : "sweeps/") + r.channel +
          "/";
      EXPECT_EQ(sd.filename.rfind(dir, 0), 0u) << sd.filename;
      EXPECT_TRUE(std::filesystem::exists(nusc.DataPath(chain[i])))
          << sd.filename;
      keyframes += sd.is_key_frame;
    }
    EXPECT_EQ(keyframes, static_cast<int>(nusc.samples().size())) << r.channel;
  }
  for (size_t s = 1; s < nusc.samples().size(); ++s) {
    EXPECT_NEAR(nusc.samples()[s].timestamp - nusc.samples()[s - 1].timestamp,
                5e5, 1000.0);
    EXPECT_EQ(nusc.samples()[s].prev, static_cast<int32_t>(s - 1));
  }
}

// 2D boxes of the annotations vs the true vehicle pixels (ray cast with the
// vehicles at the sample time and the camera at its own ego pose), for vehicles
// fully in the image and not occluded (no other surface in the box nearer than
// the box's nearest corner by 0.5 m).
TEST(NuscenesSynthetic, BoxProjectionMatchesTrueVehiclePixels) {
  const Nuscenes nusc = Load();
  const SyntheticFixture& fx = Fixture();
  const SyntheticWorld world(SyntheticWorldOptionsFor(fx.options, 0));
  const SyntheticTimeline timeline = MakeSyntheticTimeline(fx.options, 0);
  const int32_t cam = nusc.FindSensor("CAM_FRONT");
  int checked = 0;
  double min_iou = 1;
  for (const auto& sample : nusc.samples()) {
    const int32_t sd = sample.data[cam];
    ASSERT_NE(sd, kNoIndex);
    const double t = timeline.Seconds(sample.timestamp);
    const PinholeCamera camera = nusc.Camera(sd);
    const RenderedView view =
        world.RenderCamera(camera, nusc.WorldFromSensor(sd), t);
    const auto vehicles = world.Vehicles(t);
    for (const CameraBox& cb : CameraBoxes2d(nusc, sd)) {
      if (!BoxInImage(cb.box_in_cam, camera.K(), camera.width, camera.height,
                      BoxVisibility::kAll)) {
        continue;
      }
      const Eigen::Vector3d center =
          nusc.sample_annotations()[cb.box_in_cam.annotation].translation;
      int id = -1;
      for (const auto& v : vehicles) {
        if ((v.center - center).norm() < 1e-3) id = v.id;
      }
      ASSERT_GE(id, 0) << "annotation matches no vehicle";
      double near = 1e9;
      for (const auto& c : cb.box_in_cam.Corners())
        near = std::min(near, c.z());
      int pixels = 0;
      bool occluded = false;
      Box2d truth{1e9, 1e9, -1e9, -1e9};
      const Box2d& b = cb.box_2d;
      for (int v = std::max(0, int(b.ymin));
           v <= std::min(camera.height - 1, int(b.ymax)); ++v) {
        for (int u = std::max(0, int(b.xmin));
             u <= std::min(camera.width - 1, int(b.xmax)); ++u) {
          const uint16_t inst = view.instance.at<uint16_t>(v, u);
          const float depth = view.depth.at<float>(v, u);
          if (inst == id + 1) {
            ++pixels;
            truth = {
                std::min(truth.xmin, u - 0.5), std::min(truth.ymin, v - 0.5),
                std::max(truth.xmax, u + 0.5), std::max(truth.ymax, v + 0.5)};
          } else if (depth > 0 && depth < near - 0.5) {
            occluded = true;
          }
        }
      }
      if (occluded || pixels < 100) continue;
      const double iou = IoU(b, truth);
      EXPECT_GE(iou, 0.9) << "vehicle " << id << " at t=" << t;
      min_iou = std::min(min_iou, iou);
      ++checked;
    }
  }
  std::cout << checked << " unoccluded vehicle boxes, min IoU " << min_iou
            << "\n";
  EXPECT_GT(checked, 3);
}

}  // namespace
}  // namespace geodrive
