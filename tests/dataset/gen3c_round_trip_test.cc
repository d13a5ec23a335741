// The GEN3C export read back (`--geometry npz` on OUT/gen3c/<clip>/:
// geometry/reconstruction/gen3c_export.cc): the export of the shared fixture
// (tests/dataset/export_gen3c_fixture.h) rebuilt into a pair at the export's
// own size and framing, against the export and the original pair; and the
// reader's errors on small hand-made clip folders.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "dataset/build_dataset.h"
#include "dataset/internal/pair_builder.h"
#include "dataset/pairs.h"
#include "geometry/npz.h"
#include "geometry/reconstruction.h"
#include "geometry/util/status.h"
#include "render/video/h264.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"
#include "tests/dataset/export_gen3c_fixture.h"

namespace geodrive {
namespace gen3c_round_trip_test {

namespace fs = std::filesystem;
namespace fx = export_gen3c_fixture;

// build-dataset --geometry npz --monst3r OUT/gen3c over the fixture's clip at
// the export's size and framing (704x1280, centre crop) with one-pixel splats
// (--splat-radius 0): frame 0 re-renders the export's own depth through its
// own camera, so every pixel lands on itself.
BuildDatasetOptions RebuildOptions(const std::string& out) {
  BuildDatasetOptions o;
  o.dataroot = fx::World();
  o.monst3r_root = fx::Export() + "/gen3c";
  o.geometry = "npz";
  o.out = out;
  o.quiet = true;
  o.clip_frames = fx::kFrames;
  o.clips = {fx::kClip};
  o.width = fx::kWidth;
  o.height = fx::kHeight;
  o.resize_mode = ResizeMode::kCenterCrop;
  o.splat_radius_px = 0;
  return o;
}

// Frame `t` of the export's depth: the fraction of pixels with a depth
// below `far` (0 < d < far).
double ExportCoverage(const NpyArray& depth, int t, double far = 1e9) {
  const int64_t n = int64_t{fx::kWidth} * fx::kHeight;
  const float* d = depth.Data<float>() + t * n;
  int64_t drawn = 0;
  for (int64_t i = 0; i < n; ++i) drawn += d[i] > 0 && d[i] < far;
  return static_cast<double>(drawn) / n;
}

// The static PSNR formula of the pair builder on the export read as GEN3C
// reads it: rgb.mp4 frame 0 on the pixels with a depth, against the clip's
// frame 0 at the export's framing, outside every vehicle box (grown 4 px).
double ReferenceStaticPsnr(const NpyArray& depth,
                           const cv::Mat& rgb0,
                           const BuildDatasetOptions& o) {
  DriveClip clip = fx::LoadClip();
  const BoxSequences boxes =
      internal::ClipVehicleBoxes(clip, /*metric=*/true, o);
  clip.frames.resize(1);
  const cv::Mat gt0 = internal::ReadClipFrames(clip, o, 0).gt.front();
  cv::Mat mask(fx::kHeight, fx::kWidth, CV_8UC1);
  for (int y = 0; y < fx::kHeight; ++y)
    for (int x = 0; x < fx::kWidth; ++x)
      mask.at<uint8_t>(y, x) =
          depth.Data<float>()[int64_t{y} * fx::kWidth + x] > 0 ? 255 : 0;
  for (const BoxSequence& seq : boxes.instances) {
    const BoxFrame* bf = seq.Find(0);
    if (!bf || !bf->box_2d) continue;
    const Box2d b = bf->box_2d->Clipped(fx::kWidth, fx::kHeight);
    if (b.Area() <= 0) continue;
    cv::rectangle(mask,
                  cv::Rect(cv::Point(static_cast<int>(b.xmin) - 4,
                                     static_cast<int>(b.ymin) - 4),
                           cv::Point(static_cast<int>(b.xmax) + 5,
                                     static_cast<int>(b.ymax) + 5)),
                  cv::Scalar(0), cv::FILLED);
  }
  return internal::MaskedPsnr(rgb0, gt0, mask).value();
}

// The rebuilt pair against the export and the original pair. The export
// holds the condition's depth but not its colours (GEN3C colours its cache
// from rgb.mp4), and the npz path builds the scene from frame 0 (the
// paper's scaffold): the round trip is defined at frame 0, where the
// rebuilt condition is the export's depth drawn with rgb.mp4's colours.
TEST(Gen3cRoundTrip, NpzGeometryRebuildsTheExportedFrameZero) {
  const std::string out = test::MakeTempDir("gen3c_round_trip");
  const BuildDatasetOptions o = RebuildOptions(out);
  const BuildDatasetSummary s = BuildDataset(o);
  std::printf("rebuilt: %s\n", s.BriefReport().c_str());
  ASSERT_EQ(s.built, 1) << test::ReadFile(out + "/failures.jsonl");
  const PairMeta m = ReadPairMeta(out + "/pairs/" + fx::kClip);
  const PairMeta orig = ReadPairMeta(fx::Export() + "/pairs/" + fx::kClip);
  EXPECT_EQ(m.geometry_source, "npz");
  EXPECT_EQ(m.pose_units, "metres");
  // The same clip: frames, and poses up to the LiDAR fit's scale of the
  // stated metres (rotations to float32, translations x scale).
  ASSERT_EQ(m.frames.size(), orig.frames.size());
  ASSERT_EQ(m.world_from_cam.size(), orig.world_from_cam.size());
  double rot = 0, trans = 0;
  for (size_t t = 0; t < m.frames.size(); ++t) {
    EXPECT_EQ(m.frames[t].timestamp_us, orig.frames[t].timestamp_us) << t;
    EXPECT_EQ(m.frames[t].filename, orig.frames[t].filename) << t;
    const Rigid3d& a = m.world_from_cam[t];
    const Rigid3d& b = orig.world_from_cam[t];
    rot = std::max(rot, a.rotation.angularDistance(b.rotation));
    trans = std::max(trans, (a.translation - m.scale * b.translation).norm());
  }
  std::printf(
      "LiDAR scale %.6f; poses: worst rotation %.2e rad, "
      "translation %.2e m\n",
      m.scale, rot, trans);
  EXPECT_LT(rot, 1e-5);  // float32 w2c
  EXPECT_LT(trans, 1e-4);
  // Frame 0: the same pixels and the same static PSNR as the export read
  // as GEN3C reads it.
  const NpyArray depth = NpzReader(fx::ClipDir() + "/depth.npz").Read("depth");
  cv::Mat rgb0;
  ASSERT_TRUE(VideoFrameStream(fx::ClipDir() + "/rgb.mp4").Next(&rgb0));
  const double n = double{fx::kWidth} * fx::kHeight;
  const double cov0 = ExportCoverage(depth, 0);
  // The LiDAR fit scales the stated metres (by 1.0008): the exported depths
  // that it carries past the 100 m far plane are not drawn.
  const double kept0 = ExportCoverage(depth, 0, 100 / m.scale);
  const double psnr0 = ReferenceStaticPsnr(depth, rgb0, o);
  ASSERT_TRUE(m.quality.psnr_static.front().has_value());
  std::printf(
      "frame 0: coverage %.6f rebuilt vs %.6f exported (%+.0f px; %.0f "
      "exported px within the scale's band below 100 m); static PSNR %.3f dB "
      "rebuilt vs %.3f dB (rgb.mp4 on the exported depth)\n",
      m.quality.coverage.front(), cov0, (m.quality.coverage.front() - cov0) * n,
      (cov0 - kept0) * n, *m.quality.psnr_static.front(), psnr0);
  for (const int t : {30, 60, 120}) {
    std::printf(
        "frame %d (frame 0's scaffold): coverage %.4f vs exported %.4f\n", t,
        m.quality.coverage[t], ExportCoverage(depth, t));
  }
  // Every exported pixel the far plane keeps, and no other: to the pixel.
  EXPECT_NEAR(m.quality.coverage.front(), kept0, 0.5 / n);
  EXPECT_NEAR(m.quality.coverage.front(), cov0, 20 / n);
  EXPECT_NEAR(*m.quality.psnr_static.front(), psnr0, 0.1);
}

// A small clip folder: `frames` frames of 48x32 (W x H), depth 10 m, the
// camera 1 m forward per frame; `video_frames` and `video_width` for rgb.mp4.
struct SmallClip {
  int frames = 3, video_frames = 3, video_width = 48;
  int pose_frames = 3;
  NpyDtype depth_dtype = NpyDtype::kFloat32;
  std::vector<int64_t> k_shape = {3, 3, 3};
};

void WriteSmallClip(const SmallClip& c, const std::string& dir) {
  fs::create_directories(dir);
  const int w = 48, h = 32;
  NpyArray depth = NpyArray::Zeros(c.depth_dtype, {c.frames, h, w});
  for (int64_t i = 0; i < depth.NumElements(); ++i) {
    if (c.depth_dtype == NpyDtype::kFloat32)
      depth.MutableData<float>()[i] = 10.0f;
    else
      depth.MutableData<double>()[i] = 10.0;
  }
  WriteNpz(dir + "/depth.npz", {{"depth", std::move(depth)}});
  std::vector<float> w2c, k;
  for (int i = 0; i < c.pose_frames; ++i) {
    const float m[16] = {1, 0, 0, 0,         0, 1, 0, 0,
                         0, 0, 1, -1.0f * i, 0, 0, 0, 1};
    w2c.insert(w2c.end(), m, m + 16);
  }
  int64_t k_count = 1;
  for (const int64_t d : c.k_shape) k_count *= d;
  for (int64_t i = 0; i < k_count; i += 9) {
    const float m[9] = {40, 0, 23.5f, 0, 40, 15.5f, 0, 0, 1};
    k.insert(k.end(), m, m + std::min<int64_t>(9, k_count - i));
  }
  WriteNpz(dir + "/camera.npz",
           {{"w2c", NpyArray::Float32({c.pose_frames, 4, 4}, w2c.data())},
            {"intrinsics", NpyArray::Float32(c.k_shape, k.data())}});
  std::vector<cv::Mat> rgb;
  for (int i = 0; i < c.video_frames; ++i)
    rgb.emplace_back(h, c.video_width, CV_8UC3, cv::Scalar(40 * i, 90, 200));
  WriteH264Mp4(dir + "/rgb.mp4", rgb);
}

void ExpectError(const std::string& dir, const std::string& needle) {
  try {
    ReadReconstruction(ReconstructionFormat::kGenericNpz, dir);
    ADD_FAILURE() << "no error for " << dir;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
        << e.what();
  }
}

// The folder (or its depth.npz) is found under the generic npz's name and
// read in MonST3R's conventions; each inconsistent file is one error naming
// it and what is wrong.
TEST(Gen3cRoundTrip, ReaderChecksEveryFileAgainstTheOthers) {
  RegisterVideoDecoderForReconstructions();
  const std::string root = test::MakeTempDir("gen3c_reader");
  WriteSmallClip({}, root + "/good");
  EXPECT_EQ(DetectReconstructionFormat(root + "/good"),
            ReconstructionFormat::kGenericNpz);
  EXPECT_EQ(DetectReconstructionFormat(root + "/good/depth.npz"),
            ReconstructionFormat::kGenericNpz);
  const Monst3rFolder r =
      ReadReconstruction(ReconstructionFormat::kGenericNpz, root + "/good");
  EXPECT_EQ(r.format(), "GEN3C export");
  EXPECT_EQ(CreateReconstructionReaderFor(ReconstructionFormat::kGenericNpz,
                                          root + "/good")
                ->ToolName(),
            "GEN3C export");
  EXPECT_EQ(r.units(), "metres");
  EXPECT_EQ(r.grid_resize(), GridResize::kCenterCrop);
  ASSERT_EQ(r.num_frames(), 3);
  EXPECT_EQ(r.width(), 48);
  EXPECT_EQ(r.height(), 32);
  EXPECT_TRUE(r.has_rgb());
  // w2c inverted: the camera centre 1 m forward per frame.
  EXPECT_NEAR(r.trajectory().world_from_cam[2].translation.z(), 2.0, 1e-6);
  EXPECT_DOUBLE_EQ(r.cameras()[1].cx, 23.5);
  const Monst3rFrame f = r.LoadFrame(1);
  EXPECT_EQ(f.depth.at<float>(5, 7), 10.0f);
  EXPECT_NEAR(f.rgb.at<cv::Vec3b>(16, 24)[0], 40, 3);  // H.264
  // The centre crop from a 1600x900 source: 1600x880 scaled by 0.03.
  const ImageResizeSpec spec = r.SourceToGrid(1600, 900);
  EXPECT_EQ(spec.width, 48);
  EXPECT_EQ(spec.height, 32);

  SmallClip c;
  c.pose_frames = 2;
  WriteSmallClip(c, root + "/poses");
  ExpectError(root + "/poses",
              "camera.npz: w2c has 2 frames but depth.npz has 3");
  c = {};
  c.depth_dtype = NpyDtype::kFloat64;
  WriteSmallClip(c, root + "/dtype");
  ExpectError(root + "/dtype", "depth.npz: depth is <f8, expected float32");
  c = {};
  c.k_shape = {3, 3, 4};
  WriteSmallClip(c, root + "/k");
  ExpectError(root + "/k",
              "camera.npz: intrinsics: shape (3, 3, 4), expected (T, 3, 3)");
  c = {};
  c.video_frames = 4;
  WriteSmallClip(c, root + "/long");
  ExpectError(root + "/long",
              "rgb.mp4: 4 frames but the reconstruction's other files have 3");
  c = {};
  c.video_width = 64;
  WriteSmallClip(c, root + "/wide");
  ExpectError(root + "/wide",
              "rgb.mp4: frames are 64x32 but the "
              "reconstruction's other files are 48x32");
  fs::remove(root + "/long/rgb.mp4");  // no video: not a GEN3C folder
  EXPECT_EQ(DetectReconstructionFormat(root + "/long"), std::nullopt);
  SetReconstructionVideoDecoder(nullptr);
  ExpectError(root + "/good", "rgb.mp4: this program decodes no video");
  ReconstructionReadOptions no_images;  // what `geodrive info` reads
  no_images.images = false;
  const Monst3rFolder arrays = ReadReconstruction(
      ReconstructionFormat::kGenericNpz, root + "/good", no_images);
  EXPECT_EQ(arrays.num_frames(), 3);
  EXPECT_FALSE(arrays.has_rgb());
  SetReconstructionVideoDecoder(ReadVideoFramesExactly);
}

}  // namespace gen3c_round_trip_test
}  // namespace geodrive
