// The training-pair loader: padding / resizing / normalisation against direct
// formulas, the seeded epoch order, the prefetch bound and stream positions on
// pairs built from the synthetic world, and bad input.

#include "diffusion/pairs_loader.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <set>

#include "dataset/build_dataset.h"
#include "dataset/synthetic/synthetic_dataset.h"
#include "geometry/util/status.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace diffusion {

namespace fs = std::filesystem;

// A tiny pairs dataset shared by the diffusion tests: one synthetic scene
// (320x180 camera, 8.5 s) -> 4 clips of 25 frames at 96x64, built with the
// dataset library; train.jsonl = the first 3 pairs, val.jsonl = the last.
std::string DiffusionPairsFixture() {
  static const std::string out =
      test::SharedFixtureDir("diffusion_pairs", [](const std::string& dir) {
        SyntheticDatasetOptions so;
        so.num_scenes = 1;
        so.seed = 21;
        so.image_width = 320;
        so.image_height = 180;
        so.scene_duration_s = 8.5;
        so.write_monst3r = true;
        WriteSyntheticDataset(so, dir + "/world");
        BuildDatasetOptions bo;
        bo.dataroot = dir + "/world";
        bo.monst3r_root = dir + "/world/monst3r";
        bo.out = dir;
        bo.width = 96;
        bo.height = 64;
        bo.quiet = true;
        const BuildDatasetSummary s = BuildDataset(bo);
        std::printf("diffusion pairs fixture: %s\n", s.BriefReport().c_str());
        std::ifstream in(dir + "/manifest.jsonl");
        std::vector<std::string> lines;
        for (std::string l; std::getline(in, l);) {
          if (!l.empty()) lines.push_back(l);
        }
        std::ofstream train(dir + "/train.jsonl"), val(dir + "/val.jsonl");
        for (size_t i = 0; i < lines.size(); ++i)
          (i + 1 < lines.size() ? train : val) << lines[i] << "\n";
      });
  return out;
}

namespace {

cv::Mat Solid(int w, int h, cv::Vec3b c) { return cv::Mat(h, w, CV_8UC3, c); }

TEST(PairsLoader, PrepareClipPadsRepeatingTheLastFrameAndNormalises) {
  std::vector<cv::Mat> frames = {Solid(8, 6, {0, 0, 0}),
                                 Solid(8, 6, {255, 255, 255}),
                                 Solid(8, 6, {51, 102, 204})};
  const auto out = PrepareClip(frames, 5, 8, 6, "resize", "clip");
  ASSERT_EQ(out.size(), 5u);
  for (const auto& f : out) {
    EXPECT_EQ(f.type(), CV_32FC3);
    EXPECT_EQ(f.cols, 8);
    EXPECT_EQ(f.rows, 6);
  }
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(out[0].at<cv::Vec3f>(2, 3)[c], -1.0f, 1e-6);
    EXPECT_NEAR(out[1].at<cv::Vec3f>(2, 3)[c], 1.0f, 1e-6);
  }
  // x / 127.5 - 1 in float: 51 -> -0.6, 102 -> -0.2, 204 -> 0.6.
  const cv::Vec3f last = out[2].at<cv::Vec3f>(0, 0);
  EXPECT_NEAR(last[0], -0.6f, 1e-6);
  EXPECT_NEAR(last[1], -0.2f, 1e-6);
  EXPECT_NEAR(last[2], 0.6f, 1e-6);
  EXPECT_GT(cv::norm(out[1], out[0], cv::NORM_INF), 1.9);  // own buffers
  for (int i = 3; i < 5; ++i) {
    EXPECT_EQ(cv::norm(out[static_cast<size_t>(i)], out[2], cv::NORM_INF), 0.0)
        << "frame " << i << " repeats the last one";
  }
  // Truncation keeps the first frames.
  EXPECT_EQ(PrepareClip(frames, 2, 8, 6, "resize", "clip").size(), 2u);
  EXPECT_THROW(PrepareClip({}, 5, 8, 6, "resize", "clip"), InputError);
}

TEST(PairsLoader, ResizeModesDistortOrCropTheCentre) {
  // 20x10: left quarter red, middle half green, right quarter blue.
  cv::Mat img = Solid(20, 10, {0, 255, 0});
  img(cv::Rect(0, 0, 5, 10)).setTo(cv::Vec3b(255, 0, 0));
  img(cv::Rect(15, 0, 5, 10)).setTo(cv::Vec3b(0, 0, 255));
  // center-crop to 10x10: scale 1, keep columns 5..14 = all green.
  const auto crop = PrepareClip({img}, 1, 10, 10, "center-crop", "c")[0];
  double lo, hi;
  std::vector<cv::Mat> ch;
  cv::split(crop, ch);
  cv::minMaxLoc(ch[1], &lo, &hi);
  EXPECT_NEAR(lo, 1.0, 1e-6);  // green everywhere
  cv::minMaxLoc(ch[0], &lo, &hi);
  EXPECT_NEAR(hi, -1.0, 1e-6);  // no red
  // resize to 10x10 squeezes: the red quarter survives at the left edge.
  const auto sq = PrepareClip({img}, 1, 10, 10, "resize", "c")[0];
  EXPECT_NEAR(sq.at<cv::Vec3f>(5, 0)[0], 1.0f, 1e-6);
  EXPECT_NEAR(sq.at<cv::Vec3f>(5, 9)[2], 1.0f, 1e-6);
}

TEST(PairsLoader, EpochOrderIsASeededPermutation) {
  const auto a = EpochOrder(50, 7, 0, true);
  const std::set<int64_t> s(a.begin(), a.end());
  EXPECT_EQ(s.size(), 50u);
  EXPECT_EQ(*s.begin(), 0);
  EXPECT_EQ(*s.rbegin(), 49);
  EXPECT_EQ(a, EpochOrder(50, 7, 0, true));
  EXPECT_NE(a, EpochOrder(50, 7, 1, true));
  EXPECT_NE(a, EpochOrder(50, 8, 0, true));
  const auto id = EpochOrder(5, 7, 3, false);
  EXPECT_EQ(id, (std::vector<int64_t>{0, 1, 2, 3, 4}));
}

TEST(PairsLoader, StreamsBuiltPairsInSeededOrderThroughABoundedQueue) {
  const std::string dir = DiffusionPairsFixture();
  PairsLoaderOptions o;
  o.manifest = dir + "/manifest.jsonl";
  o.frames = 49;
  o.width = 48;
  o.height = 32;
  o.seed = 3;
  o.prefetch = 2;
  o.start_sample = 2;
  o.num_samples = 7;
  PairsLoader loader(o);
  ASSERT_EQ(loader.size(), 4);
  std::vector<PairSample> got;
  PairSample s;
  while (loader.Next(&s)) got.push_back(s);
  ASSERT_EQ(got.size(), 7u);
  EXPECT_LE(loader.max_queued(), 2);
  for (size_t i = 0; i < got.size(); ++i) {
    const int64_t k = 2 + static_cast<int64_t>(i);
    EXPECT_EQ(got[i].sample, k);
    EXPECT_EQ(got[i].pair_index, EpochOrder(4, 3, k / 4, true)[k % 4]);
    EXPECT_EQ(
        got[i].clip_id,
        loader.records()[static_cast<size_t>(got[i].pair_index)].entry.clip_id);
    EXPECT_EQ(got[i].source_frames, 25);
    ASSERT_EQ(got[i].gt.size(), 49u);
    ASSERT_EQ(got[i].cond.size(), 49u);
    EXPECT_EQ(got[i].gt[0].cols, 48);
    EXPECT_EQ(got[i].gt[0].rows, 32);
    for (int f = 25; f < 49; ++f) {
      EXPECT_EQ(cv::norm(got[i].gt[static_cast<size_t>(f)], got[i].gt[24],
                         cv::NORM_INF),
                0.0);
    }
  }
  // Frame 10 of the first sample equals the decoded video resized directly.
  const PairRecord& rec =
      loader.records()[static_cast<size_t>(got[0].pair_index)];
  EXPECT_EQ(rec.meta.resize_mode, "resize");
  const std::vector<cv::Mat> raw = ReadVideoFrames(rec.cond_video);
  ASSERT_EQ(raw.size(), 25u);
  cv::Mat expect;
  cv::resize(raw[10], expect, cv::Size(48, 32), 0, 0, cv::INTER_AREA);
  expect.convertTo(expect, CV_32FC3, 1.0 / 127.5, -1.0);
  EXPECT_EQ(cv::norm(got[0].cond[10], expect, cv::NORM_INF), 0.0);
  // GT and condition differ (the render is not the photo) but agree roughly.
  const double diff =
      cv::norm(got[0].gt[10], got[0].cond[10], cv::NORM_L1) / (48.0 * 32 * 3);
  std::printf("mean |gt - cond| at frame 10: %.3f (of range 2)\n", diff);
  EXPECT_GT(diff, 0.0);
  EXPECT_LT(diff, 0.5);
}

TEST(PairsLoader, BadInputNamesTheFile) {
  const std::string dir = DiffusionPairsFixture();
  const std::string tmp = test::MakeTempDir("pairs_loader_bad");
  PairsLoaderOptions o;
  o.manifest = tmp + "/missing.jsonl";
  try {
    PairsLoader l(o);
    FAIL() << "no throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.jsonl"), std::string::npos)
        << e.what();
  }
  // A hostile pair_dir.
  std::ifstream in(dir + "/manifest.jsonl");
  std::string line;
  std::getline(in, line);
  const size_t at = line.find("pairs/");
  ASSERT_NE(at, std::string::npos);
  std::string bad = line;
  bad.replace(at, 6, "../../");
  std::ofstream(tmp + "/hostile.jsonl") << bad << "\n";
  o.manifest = tmp + "/hostile.jsonl";
  try {
    PairsLoader l(o);
    FAIL() << "no throw";
  } catch (const InputError& e) {
    // The manifest line itself is refused, naming the file, line and field.
    EXPECT_NE(std::string(e.what()).find("hostile.jsonl:1: pair_dir: '../../"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("climbs out"), std::string::npos)
        << e.what();
  }
  // A pair whose condition video is gone: the error reaches Next().
  fs::create_directories(tmp + "/copy");
  fs::copy(dir + "/pairs", tmp + "/copy/pairs", fs::copy_options::recursive);
  std::ofstream(tmp + "/copy/manifest.jsonl") << line << "\n";
  const std::string pair_dir = line.substr(at, line.find('"', at) - at);
  fs::remove(tmp + "/copy/" + pair_dir + "/cond.mp4");
  o.manifest = tmp + "/copy/manifest.jsonl";
  try {
    PairsLoader l(o);
    FAIL() << "no throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cond.mp4"), std::string::npos)
        << e.what();
  }
  // An undecodable video: reported by Next(), naming the file.
  fs::copy(dir + "/" + pair_dir + "/cond.mp4",
           tmp + "/copy/" + pair_dir + "/cond.mp4");
  std::ofstream(tmp + "/copy/" + pair_dir + "/gt.mp4", std::ios::trunc)
      << "not a video";
  PairsLoader l(o);
  PairSample s;
  try {
    l.Next(&s);
    FAIL() << "no throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("gt.mp4"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace diffusion
}  // namespace geodrive
