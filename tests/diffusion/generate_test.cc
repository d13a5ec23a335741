// `geodrive-diffusion generate` end to end with tiny random weights (backbone
// and encoder from init-weights, VAE from --seed) on a synthetic MonST3R
// folder and on an image + depth + intrinsics input.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <string>
#include <thread>

#include "dataset/pairs.h"
#include "diffusion/safetensors.h"
#include "geometry/camera.h"
#include "geometry/image_io.h"
#include "geometry/npy.h"
#include "geometry/npz.h"
#include "geometry/reconstruction.h"
#include "geometry/trajectory.h"
#include "geometry/trajectory_io.h"
#include "geometry/trajectory_json.h"
#include "render/video/video_io.h"
#include "tests/common/temporaries.h"
#include "tests/common/test_util.h"
#include "tests/diffusion/diffusion_test_util.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;

constexpr int kW = 64, kH = 48;

// A colourful image of a slanted plane (depth 4 .. 5.9 from top to bottom).
void SceneImageAndDepth(cv::Mat* rgb, cv::Mat* depth) {
  *rgb = cv::Mat(kH, kW, CV_8UC3);
  *depth = cv::Mat(kH, kW, CV_32F);
  for (int j = 0; j < kH; ++j) {
    for (int i = 0; i < kW; ++i) {
      rgb->at<cv::Vec3b>(j, i) =
          cv::Vec3b(static_cast<uint8_t>(4 * i), static_cast<uint8_t>(5 * j),
                    static_cast<uint8_t>(((i / 8 + j / 8) % 2) * 200 + 20));
      depth->at<float>(j, i) = 4.0f + 0.04f * j;
    }
  }
}

PinholeCamera SceneCamera() {
  return PinholeCamera(50.0, 50.0, 32.0, 24.0, kW, kH);
}

// Forward motion of 0.1 per frame with a slight yaw.
Trajectory ForwardTrajectory(int n) {
  Trajectory t;
  for (int k = 0; k < n; ++k) {
    const Eigen::Quaterniond q(
        Eigen::AngleAxisd(0.01 * k, Eigen::Vector3d::UnitY()));
    t.Add(0.1 * k, Rigid3d(q, Eigen::Vector3d(0.02 * k, 0.0, 0.1 * k)));
  }
  return t;
}

void WriteDepthNpy(const std::string& path, const cv::Mat& depth) {
  WriteNpy(path, NpyArray::Float32({depth.rows, depth.cols},
                                   reinterpret_cast<float*>(depth.data)));
}

// A MonST3R output folder (pred_traj.txt, pred_intrinsics.txt,
// frame_%04d.npy/png) of `n` frames that all see the same plane.
std::string WriteMonst3rFolder(const std::string& root, int n) {
  const std::string dir = root + "/monst3r";
  fs::create_directories(dir);
  cv::Mat rgb, depth;
  SceneImageAndDepth(&rgb, &depth);
  const Trajectory traj = ForwardTrajectory(n);
  WriteMonst3rTrajectory(dir + "/pred_traj.txt", traj);
  WriteMonst3rIntrinsics(dir + "/pred_intrinsics.txt",
                         std::vector<PinholeCamera>(n, SceneCamera()));
  for (int i = 0; i < n; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "/frame_%04d", i);
    WriteDepthNpy(dir + name + ".npy", depth);
    WriteImageRgb(dir + name + ".png", rgb);
  }
  return dir;
}

std::string TinyWeights(const std::string& dir) {
  const std::string w = dir + "/tiny.safetensors";
  std::string out;
  EXPECT_EQ(test::RunCommand(test::DiffusionCommand() +
                                 " init-weights --config tiny --seed 3 "
                                 "--nonzero-branch --out " +
                                 w,
                             &out),
            0)
      << out;
  return w;
}

TEST(DiffusionGenerate, Monst3rFolderEndToEndWritesRequestedFrames) {
  const std::string dir = test::MakeTempDir("generate_monst3r");
  const std::string m3r = WriteMonst3rFolder(dir, 9);
  const std::string w = TinyWeights(dir);
  const std::string common = test::DiffusionCommand() +
                             " generate --geometry " + m3r + " --weights " + w +
                             " --config tiny --frames 7 --steps 2 "
                             "--no-progress --seed 5 --out ";
  std::string out;
  ASSERT_EQ(test::RunCommand(common + dir + "/a/video.mp4", &out), 0) << out;
  std::cout << out;
  // tiny: 3 latent frames -> 9 model frames at 48x32; 7 asked for.
  const std::vector<cv::Mat> frames = ReadVideoFrames(dir + "/a/video.mp4");
  ASSERT_EQ(frames.size(), 7u);
  EXPECT_EQ(frames[0].cols, 48);
  EXPECT_EQ(frames[0].rows, 32);
  EXPECT_TRUE(fs::exists(dir + "/a/video_preview.png"));
  for (const char* f : {"image", "cond", "sample"}) {
    EXPECT_TRUE(fs::exists(dir + "/a/video_latents/" + f + ".safetensors"))
        << f;
  }
  // Same inputs and seed -> byte-identical latents.
  ASSERT_EQ(test::RunCommand(common + dir + "/b/video.mp4", &out), 0) << out;
  for (const char* f : {"cond", "sample"}) {
    const std::string name =
        std::string("/video_latents/") + f + ".safetensors";
    EXPECT_EQ(test::ReadFile(dir + "/a" + name),
              test::ReadFile(dir + "/b" + name))
        << f;
  }
  // --boxes: one object whose 2D box slides right; the 2D dynamic edit pastes
  // its frame-0 crop along the track, so the condition render changes.
  {
    std::ofstream b(dir + "/boxes.json");
    b << "{\"format\": \"geodrive-boxes\", \"version\": 1, "
         "\"image_width\": 64, \"image_height\": 48, \"num_frames\": 7, "
         "\"units\": \"metres\", \"instances\": [{\"id\": \"car-1\", "
         "\"category\": \"vehicle.car\", \"frames\": [";
    for (int k = 0; k < 7; ++k) {
      b << (k ? ", " : "") << "{\"frame\": " << k << ", \"box_2d\": ["
        << 8 + 3 * k << ", 12, " << 28 + 3 * k << ", 30]}";
    }
    b << "]}]}\n";
  }
  ASSERT_EQ(test::RunCommand(common + dir + "/c/video.mp4 --boxes " + dir +
                                 "/boxes.json --edit-mode 2d",
                             &out),
            0)
      << out;
  EXPECT_NE(out.find("dynamic edit (2d): 1 object(s) over 7 frames"),
            std::string::npos)
      << out;
  EXPECT_EQ(ReadVideoFrames(dir + "/c/video.mp4").size(), 7u);
  EXPECT_NE(test::ReadFile(dir + "/a/video_latents/cond.safetensors"),
            test::ReadFile(dir + "/c/video_latents/cond.safetensors"));
}

TEST(DiffusionGenerate, ImageDepthIntrinsicsWithUserTrajectory) {
  const std::string dir = test::MakeTempDir("generate_depth");
  cv::Mat rgb, depth;
  SceneImageAndDepth(&rgb, &depth);
  WriteImageRgb(dir + "/first.png", rgb);
  WriteDepthNpy(dir + "/depth.npy", depth);
  {
    std::ofstream k(dir + "/K.txt");
    k << "50 0 32\n0 50 24\n0 0 1\n";
  }
  WriteTrajectoryJson(dir + "/traj.json", ForwardTrajectory(5));
  const std::string w = TinyWeights(dir);
  std::string out;
  ASSERT_EQ(
      test::RunCommand(
          test::DiffusionCommand() + " generate --image " + dir +
              "/first.png --depth " + dir + "/depth.npy --intrinsics " + dir +
              "/K.txt --trajectory " + dir + "/traj.json --weights " + w +
              " --steps 1 --scheduler ddim --no-progress "
              "--out " +
              dir + "/gen.mp4",
          &out),
      0)
      << out;
  // Default --frames: min(9 model frames, 5 poses).
  EXPECT_EQ(ReadVideoFrames(dir + "/gen.mp4").size(), 5u) << out;
}

// A condition video made elsewhere (geodrive plan --videos): the sample is
// conditioned on its frames, nothing is rendered; its latents are those of
// the video's frames. Geometry options and too many --frames are refused.
TEST(DiffusionGenerate, ReadyConditionVideoWithFirstFrame) {
  const std::string dir = test::MakeTempDir("generate_condition");
  cv::Mat rgb, depth;
  SceneImageAndDepth(&rgb, &depth);
  WriteImageRgb(dir + "/first.png", rgb);
  std::vector<cv::Mat> cond;
  for (int k = 0; k < 6; ++k) {
    cv::Mat f = rgb.clone();
    f.colRange(0, 4 + 4 * k).setTo(cv::Scalar(0, 0, 0));
    cond.push_back(f);
  }
  WriteVideoFrames(dir + "/cond.mp4", cond, 10);
  const std::string w = TinyWeights(dir);
  const std::string base = test::DiffusionCommand() + " generate --image " +
                           dir + "/first.png --condition " + dir +
                           "/cond.mp4 --weights " + w +
                           " --steps 1 --scheduler ddim --no-progress";
  std::string out;
  ASSERT_EQ(test::RunCommand(base + " --out " + dir + "/gen.mp4", &out), 0)
      << out;
  // Default --frames: min(9 model frames, 6 condition frames).
  EXPECT_EQ(ReadVideoFrames(dir + "/gen.mp4").size(), 6u) << out;
  EXPECT_NE(out.find("condition video " + dir + "/cond.mp4"), std::string::npos)
      << out;
  // Another condition video gives other condition latents.
  std::reverse(cond.begin(), cond.end());
  WriteVideoFrames(dir + "/cond2.mp4", cond, 10);
  ASSERT_EQ(test::RunCommand(test::DiffusionCommand() + " generate --image " +
                                 dir + "/first.png --condition " + dir +
                                 "/cond2.mp4 --weights " + w +
                                 " --steps 1 --scheduler ddim --no-progress "
                                 "--out " +
                                 dir + "/gen2.mp4",
                             &out),
            0)
      << out;
  EXPECT_NE(test::ReadFile(dir + "/gen_latents/cond.safetensors"),
            test::ReadFile(dir + "/gen2_latents/cond.safetensors"));
  for (const std::string bad :
       {std::string(" --frames 7"), " --depth " + dir + "/x.npy",
        " --trajectory " + dir + "/t.json"}) {
    EXPECT_EQ(test::RunCommand(base + bad + " --out " + dir + "/bad.mp4", &out),
              2)
        << bad << ": " << out;
    EXPECT_FALSE(fs::exists(dir + "/bad.mp4")) << bad;
  }
}

// Batch mode over a build-dataset output (two hand-made 11-frame pairs): one
// <clip_id>.mp4 per pair in --out-dir, which `geodrive eval` lists by clip id.
TEST(DiffusionGenerate, ManifestBatchWritesOneVideoPerPair) {
  const std::string dir = test::MakeTempDir("generate_manifest");
  cv::Mat rgb, depth;
  SceneImageAndDepth(&rgb, &depth);
  fs::create_directories(dir + "/build");
  std::ofstream manifest(dir + "/build/manifest.jsonl");
  for (const std::string clip : {"clip-a", "clip-bad", "clip-b"}) {
    const std::string pdir = dir + "/build/pairs/" + clip;
    fs::create_directories(pdir);
    std::vector<cv::Mat> gt, cond;
    for (int k = 0; k < 11; ++k) {
      cv::Mat f = rgb.clone();
      f.colRange(0, 4 + 2 * k).setTo(cv::Scalar(0, 0, 0));
      gt.push_back(rgb.clone());
      cond.push_back(f);
    }
    WriteVideoFrames(pdir + "/gt.mp4", gt, 10);
    WriteVideoFrames(pdir + "/cond.mp4", cond, 10);
    PairMeta meta;
    meta.clip_id = clip;
    meta.scene_name = "scene-0001";
    meta.intrinsics = SceneCamera();
    meta.resize_mode = "resize";
    meta.pose_units = "metres";
    meta.scale_source = "none";
    meta.geometry_source = "monst3r";
    meta.preset = "paper";
    meta.edit_mode = "none";
    meta.options_json = "{}";
    meta.world_from_cam.assign(11, Rigid3d());
    meta.frames.resize(11);
    meta.files = {{"gt", "gt.mp4"}, {"cond", "cond.mp4"}};
    std::ofstream(pdir + "/meta.json") << PairMetaToJson(meta);
    ManifestEntry e;
    e.clip_id = clip;
    e.pair_dir = "pairs/" + clip;
    e.scene_name = meta.scene_name;
    e.num_frames = 11;
    manifest << ManifestEntryToJson(e) << "\n";
    if (clip == "clip-bad") fs::remove(pdir + "/cond.mp4");
  }
  manifest.close();
  const std::string w = TinyWeights(dir);
  std::string out;
  // Options are checked before any pair is read or rendered: nothing is
  // created for a bad --steps, --guidance or --fps.
  for (const char* bad : {"--steps 0", "--guidance nan", "--fps 0"}) {
    EXPECT_EQ(
        test::RunCommand(test::DiffusionCommand() + " generate --manifest " +
                             dir + "/build/manifest.jsonl --out-dir " + dir +
                             "/early --weights " + w + " " + bad,
                         &out),
        2)
        << bad << ": " << out;
    EXPECT_FALSE(fs::exists(dir + "/early")) << bad;
  }
  // A bad pair is recorded and skipped; the others are generated; exit 3.
  ASSERT_EQ(
      test::RunCommand(test::DiffusionCommand() + " generate --manifest " +
                           dir + "/build/manifest.jsonl --out-dir " + dir +
                           "/pred --weights " + w + " --steps 1 --no-progress",
                       &out),
      3)
      << out;
  std::cout << out;
  const std::vector<FailureEntry> failed =
      ReadFailures(dir + "/pred/failures.jsonl");
  ASSERT_EQ(failed.size(), 1u);
  EXPECT_EQ(failed[0].clip_id, "clip-bad");
  EXPECT_NE(failed[0].error.find("cond.mp4: missing"), std::string::npos)
      << failed[0].error;
  const std::vector<VideoSource> pred = ListVideos(dir + "/pred", "");
  ASSERT_EQ(pred.size(), 2u);
  EXPECT_EQ(pred[0].id, "clip-a");
  EXPECT_EQ(pred[1].id, "clip-b");
  // 11 condition frames, tiny model 9 frames: min(9, 11) per pair.
  EXPECT_EQ(ReadVideoFrames(pred[0].path).size(), 9u);
  EXPECT_TRUE(fs::exists(dir + "/pred_work/clip-b/preview.png"));
}

// `--scene npz:PATH` (any reconstruction tool's output, docs/
// RECONSTRUCTIONS.md) holding the numbers of a MonST3R folder generates what
// `--geometry` on that folder does: byte-identical latents.
TEST(DiffusionGenerate, SceneToolPathMatchesTheMonst3rFolder) {
  const std::string dir = test::MakeTempDir("generate_scene");
  const std::string m3r = WriteMonst3rFolder(dir, 9);
  const std::string w = TinyWeights(dir);
  const Monst3rFolder folder = Monst3rFolder::Open(m3r);
  const int n = folder.num_frames(), h = folder.height(), wd = folder.width();
  std::vector<float> depth;
  std::vector<double> K, c2w;
  std::vector<uint8_t> rgb;
  for (int i = 0; i < n; ++i) {
    const Monst3rFrame f = folder.LoadFrame(i);
    depth.insert(depth.end(), f.depth.ptr<float>(),
                 f.depth.ptr<float>() + h * wd);
    rgb.insert(rgb.end(), f.rgb.data, f.rgb.data + h * wd * 3);
    const Eigen::Matrix3d k = f.camera.K();
    const Eigen::Matrix4d p = f.world_from_cam.ToMatrix();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) K.push_back(k(r, c));
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) c2w.push_back(p(r, c));
  }
  WriteNpz(dir + "/scene.npz",
           {{"depth", NpyArray::Float32({n, h, wd}, depth.data())},
            {"intrinsics", NpyArray::Float64({n, 3, 3}, K.data())},
            {"cam_c2w", NpyArray::Float64({n, 4, 4}, c2w.data())},
            {"images", NpyArray::Uint8({n, h, wd, 3}, rgb.data())}});
  const std::string common = " --weights " + w +
                             " --config tiny --frames 7 --steps 2 "
                             "--no-progress --seed 5 --out ";
  std::string out;
  ASSERT_EQ(
      test::RunCommand(test::DiffusionCommand() + " generate --geometry " +
                           m3r + common + dir + "/a/video.mp4",
                       &out),
      0)
      << out;
  ASSERT_EQ(test::RunCommand(test::DiffusionCommand() +
                                 " generate --scene npz:" + dir + "/scene.npz" +
                                 common + dir + "/s/video.mp4",
                             &out),
            0)
      << out;
  for (const char* f : {"cond", "sample"}) {
    const std::string a =
        test::ReadFile(dir + "/a/video_latents/" + f + ".safetensors");
    EXPECT_FALSE(a.empty()) << f;
    EXPECT_EQ(a, test::ReadFile(dir + "/s/video_latents/" + f + ".safetensors"))
        << f;
  }
  // --scene with --geometry: one line, exit 2.
  EXPECT_EQ(
      test::RunCommand(test::DiffusionCommand() + " generate --geometry " +
                           m3r + " --scene npz:" + dir + "/scene.npz" + common +
                           dir + "/x.mp4",
                       &out),
      2);
  EXPECT_NE(out.find("exactly one of --geometry"), std::string::npos) << out;
}

// SIGTERM while sampling (1000 steps of tiny-49, about 5 s): exit 130, no
// temporary left, and nothing half-written: no video, no preview, no sample
// latents; the latents written before the signal are whole files.
TEST(DiffusionGenerate, SigtermExits130WithoutPartialOutput) {
  const std::string dir = test::MakeTempDir("generate_sigterm");
  const std::string m3r = WriteMonst3rFolder(dir, 9);
  const std::string w = dir + "/tiny49.safetensors";
  std::string log;
  ASSERT_EQ(test::RunCommand(test::DiffusionCommand() +
                                 " init-weights --config tiny-49 --seed 3 "
                                 "--nonzero-branch --out " +
                                 w,
                             &log),
            0)
      << log;
  const std::string out = dir + "/gen";
  const std::string pidfile = dir + "/pid", rcfile = dir + "/rc";
  // The subshell's own output is redirected too, so RunCommand does not wait
  // for it.
  ASSERT_EQ(test::RunCommand("(" + test::DiffusionCommand() +
                             " generate --geometry " + m3r + " --weights " + w +
                             " --config tiny-49 --frames 7 --steps 1000 "
                             "--no-progress --out " +
                             out + "/video.mp4; echo $? > " + rcfile +
                             ") > /dev/null 2>&1 & echo $! > " + pidfile),
            0);
  // The condition latents are written: sampling has begun.
  const std::string latents = out + "/video_latents";
  bool signalled = false;
  for (int i = 0; i < 1500 && !signalled && !fs::exists(rcfile); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (fs::exists(latents + "/cond.safetensors")) {
      test::RunCommand("pkill -TERM -P " + test::ReadFile(pidfile));
      signalled = true;
    }
  }
  ASSERT_TRUE(signalled) << "generate ended (exit " << test::ReadFile(rcfile)
                         << ") before its latents were written";
  for (int i = 0; i < 600 && !fs::exists(rcfile); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(test::ReadFile(rcfile), "130\n");
  EXPECT_TRUE(test::Temporaries(out).empty()) << test::Temporaries(out).front();
  EXPECT_FALSE(fs::exists(out + "/video.mp4"));
  EXPECT_FALSE(fs::exists(out + "/video_preview.png"));
  EXPECT_FALSE(fs::exists(latents + "/sample.safetensors"));
  for (const auto& e : fs::directory_iterator(latents)) {
    EXPECT_NO_THROW(diffusion::LoadSafetensors(e.path().string())) << e.path();
  }
}

TEST(DiffusionGenerate, BadArgumentsExitTwoWithOneLine) {
  const std::string dir = test::MakeTempDir("generate_bad");
  const std::string m3r = WriteMonst3rFolder(dir, 9);
  const std::string w = TinyWeights(dir);
  std::string out;
  EXPECT_EQ(test::RunCommand(test::DiffusionCommand() +
                                 " generate --geometry " + m3r + " --weights " +
                                 w + " --frames 20 --out " + dir + "/x.mp4",
                             &out),
            2);
  EXPECT_NE(out.find("--frames 20 must be in [1, 9]"), std::string::npos)
      << out;
  EXPECT_EQ(
      test::RunCommand(test::DiffusionCommand() + " generate --geometry " +
                           m3r + " --depth d.npy --weights " + w + " --out " +
                           dir + "/x.mp4",
                       &out),
      2);
  EXPECT_NE(out.find("exactly one of --geometry"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir + "/x.mp4"));
}

}  // namespace
}  // namespace geodrive
