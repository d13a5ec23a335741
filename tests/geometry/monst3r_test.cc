#include "geometry/monst3r.h"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "geometry/image_io.h"
#include "geometry/npy.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"
#include "tests/geometry/synthetic_pointmaps.h"

namespace geodrive {
namespace {

namespace fs = std::filesystem;

test::SyntheticClip SmallClip(int frames = 5) {
  test::SyntheticClipOptions o;
  o.width = 64;
  o.height = 36;
  o.focal = 58;
  o.num_frames = frames;
  return test::MakeSyntheticClip(o);
}

std::string WriteSmallFolder(const std::string& name, int frames = 5) {
  const std::string dir = test::MakeTempDir(name);
  test::Monst3rWriteOptions w;
  w.bad_depth_fraction = 0.1;
  test::WriteMonst3rFolder(SmallClip(frames), dir, w);
  return dir;
}

// Expects `fn` to throw InputError whose message contains `needle`.
template <typename Fn>
void ExpectInputError(Fn fn, const std::string& needle) {
  try {
    fn();
    ADD_FAILURE() << "no InputError (wanted one mentioning '" << needle << "')";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
        << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos)
        << "one line: " << e.what();
  }
}

TEST(Monst3rFolder, ReadsTheDemoFileSet) {
  const test::SyntheticClip clip = SmallClip();
  const std::string dir = WriteSmallFolder("monst3r_read");
  const Monst3rFolder folder = Monst3rFolder::Open(dir);
  ASSERT_EQ(folder.num_frames(), 5);
  EXPECT_EQ(folder.width(), 64);
  EXPECT_EQ(folder.height(), 36);
  EXPECT_TRUE(folder.has_confidence() && folder.has_init_confidence() &&
              folder.has_rgb());
  EXPECT_TRUE(folder.has_dynamic_masks() &&
              folder.has_enlarged_dynamic_masks());
  EXPECT_FALSE(folder.has_raw_pointmaps());
  EXPECT_DOUBLE_EQ(folder.cameras()[3].cx, 32.0);
  EXPECT_DOUBLE_EQ(folder.cameras()[3].fx, 58.0);
  // Trajectory is world_from_cam (w-first on disk).
  EXPECT_LT(RotationDistanceDeg(folder.trajectory().world_from_cam[4].rotation,
                                clip.world_from_cam[4].rotation),
            1e-6);
  EXPECT_LT((folder.trajectory().world_from_cam[4].translation -
             clip.world_from_cam[4].translation)
                .norm(),
            1e-6);
  Monst3rLoadOptions opt;
  opt.init_confidence = true;
  const Monst3rFrame f = folder.LoadFrame(2, opt);
  ASSERT_EQ(f.depth.type(), CV_32FC1);
  EXPECT_EQ(f.rgb.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(f.rgb, clip.rgb[2], cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(f.dynamic_mask, clip.dynamic_mask[2], cv::NORM_INF), 0);
  EXPECT_GE(cv::countNonZero(f.enlarged_dynamic_mask),
            cv::countNonZero(f.dynamic_mask));
  // conf holds -inf where cleaned; init_conf does not.
  int neg_inf = 0;
  for (int v = 0; v < f.log_confidence.rows; ++v) {
    for (int u = 0; u < f.log_confidence.cols; ++u) {
      neg_inf += std::isinf(f.log_confidence.at<float>(v, u));
      EXPECT_TRUE(std::isfinite(f.init_log_confidence.at<float>(v, u)));
    }
  }
  EXPECT_GT(neg_inf, 0);
  // Partial loading: nothing but depth.
  Monst3rLoadOptions none;
  none.rgb = none.confidence = none.dynamic_masks =
      none.enlarged_dynamic_masks = false;
  const Monst3rFrame g = folder.LoadFrame(1, none);
  EXPECT_TRUE(g.rgb.empty() && g.log_confidence.empty() &&
              g.dynamic_mask.empty());
  EXPECT_FALSE(g.depth.empty());
}

TEST(Monst3rFolder, UnpaddedIndicesAreSortedByInteger) {
  const test::SyntheticClip clip = SmallClip(12);
  const std::string dir = test::MakeTempDir("monst3r_unpadded");
  test::WriteMonst3rFolder(clip, dir);
  const Monst3rFolder folder = Monst3rFolder::Open(dir);
  ASSERT_EQ(folder.num_frames(), 12);
  EXPECT_EQ(fs::path(folder.ConfidencePath(10)).filename(), "conf_10.npy");
  EXPECT_EQ(fs::path(folder.DynamicMaskPath(2)).filename(),
            "dynamic_mask_2.png");
  EXPECT_EQ(fs::path(folder.DepthPath(10)).filename(), "frame_0010.npy");
  // Frame 10's mask is frame 10's (a string sort would put 10 after 1).
  for (int i : {1, 2, 10, 11}) {
    EXPECT_EQ(cv::norm(folder.LoadFrame(i).dynamic_mask, clip.dynamic_mask[i],
                       cv::NORM_INF),
              0)
        << i;
  }
}

TEST(Monst3rFolder, MissingFileIsNamed) {
  const std::string dir = WriteSmallFolder("monst3r_missing");
  fs::remove(dir + "/conf_3.npy");
  ExpectInputError([&] { Monst3rFolder::Open(dir); }, "conf_3.npy");
  const std::string dir2 = WriteSmallFolder("monst3r_missing_traj");
  fs::remove(dir2 + "/pred_traj.txt");
  ExpectInputError([&] { Monst3rFolder::Open(dir2); },
                   "pred_traj.txt: missing");
}

TEST(Monst3rFolder, MismatchedFrameCounts) {
  const std::string dir = WriteSmallFolder("monst3r_counts");
  // Drop the last pose: 4 poses for 5 depth maps.
  std::ifstream in(dir + "/pred_traj.txt");
  std::string all, line;
  for (int i = 0; i < 4 && std::getline(in, line); ++i) all += line + "\n";
  in.close();
  std::ofstream(dir + "/pred_traj.txt") << all;
  ExpectInputError([&] { Monst3rFolder::Open(dir); },
                   "mismatched frame counts");
}

TEST(Monst3rFolder, DepthShapeDifferentFromMask) {
  const std::string dir = WriteSmallFolder("monst3r_shape");
  WriteImageRgb(dir + "/dynamic_mask_2.png",
                cv::Mat(30, 64, CV_8UC1, cv::Scalar(0)));
  const Monst3rFolder folder = Monst3rFolder::Open(dir);
  folder.LoadFrame(1);
  ExpectInputError([&] { folder.LoadFrame(2); },
                   "dynamic_mask_2.png: shape 30x64");
}

TEST(Monst3rFolder, NanPose) {
  const std::string dir = WriteSmallFolder("monst3r_nan");
  std::ifstream in(dir + "/pred_traj.txt");
  std::string all, line;
  for (int i = 0; std::getline(in, line); ++i)
    all += (i == 2 ? "2.0 nan 0 0 1 0 0 0" : line) + "\n";
  in.close();
  std::ofstream(dir + "/pred_traj.txt") << all;
  ExpectInputError([&] { Monst3rFolder::Open(dir); }, "pred_traj.txt");
}

TEST(Monst3rFolder, AllMinusInfConfidence) {
  const std::string dir = WriteSmallFolder("monst3r_inf");
  std::vector<float> inf(64 * 36, -std::numeric_limits<float>::infinity());
  WriteNpy(dir + "/conf_1.npy", NpyArray::Float32({36, 64}, inf.data()));
  const Monst3rFolder folder = Monst3rFolder::Open(dir);
  ExpectInputError([&] { folder.LoadFrame(1); },
                   "conf_1.npy: confidence is not finite at any pixel (-inf");
  ExpectInputError([&] { folder.LoadFrames({0, 1, 2}); }, "conf_1.npy");
}

// A map of +inf is reported as +inf, not as "-inf (or NaN)".
TEST(Monst3rFolder, AllPlusInfConfidenceSaysPlusInf) {
  const std::string dir = WriteSmallFolder("monst3r_pinf");
  std::vector<float> inf(64 * 36, std::numeric_limits<float>::infinity());
  WriteNpy(dir + "/conf_1.npy", NpyArray::Float32({36, 64}, inf.data()));
  const Monst3rFolder folder = Monst3rFolder::Open(dir);
  ExpectInputError([&] { folder.LoadFrame(1); },
                   "conf_1.npy: confidence is not finite at any pixel (+inf");
}

// A confidence map of the wrong (huge) shape is refused from its header
// alone, before any of it is allocated or read: a 31623 x 31623 float32 map
// (4 GB declared) whose data is a sparse file, so the test writes 80 bytes of
// header and seeks.
TEST(Monst3rFolder, HugeConfidenceMapRefusedFromItsHeader) {
  const std::string dir = WriteSmallFolder("monst3r_hugeconf");
  const std::string path = dir + "/conf_0.npy";
  std::string header =
      "{'descr': '<f4', 'fortran_order': False, 'shape': (31623, 31623), }";
  header.resize(117, ' ');
  header += "\n";
  std::string preamble = "\x93NUMPY";
  preamble += '\x01';
  preamble += '\x00';
  preamble += static_cast<char>(header.size() & 0xff);
  preamble += static_cast<char>(header.size() >> 8);
  {
    std::ofstream out(path, std::ios::binary);
    out << preamble << header;
  }
  std::filesystem::resize_file(path, 128 + uint64_t{31623} * 31623 * 4);
  const Monst3rFolder folder = Monst3rFolder::Open(dir);
  rusage before{};
  getrusage(RUSAGE_SELF, &before);
  ExpectInputError([&] { folder.LoadFrame(0); },
                   "conf_0.npy: shape 31623x31623 (HxW) differs from the "
                   "depth map");
  rusage after{};
  getrusage(RUSAGE_SELF, &after);
  // ru_maxrss is in KiB: nothing near the 4 GB the header declares.
  EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 100 * 1024);
  std::filesystem::remove(path);
}

TEST(Monst3rConfidence, UnitMapping) {
  EXPECT_EQ(ConfidenceToUnit(-std::numeric_limits<float>::infinity()), 0.f);
  EXPECT_EQ(ConfidenceToUnit(std::numeric_limits<float>::quiet_NaN()), 0.f);
  EXPECT_NEAR(ConfidenceToUnit(std::log(3.f)), 2.0 / 3.0,
              1e-6);  // raw 3 -> 1 - 1/3
  EXPECT_NEAR(ConfidenceToUnit(static_cast<float>(-std::log(0.35))), 0.65,
              1e-6);  // tau
  EXPECT_NEAR(ConfidenceToUnit(3.f, ConfidenceEncoding::kRaw), 2.0 / 3.0, 1e-6);
  EXPECT_EQ(ConfidenceToUnit(0.5f, ConfidenceEncoding::kRaw), 0.f);
  EXPECT_EQ(ConfidenceToUnit(1.5f, ConfidenceEncoding::kUnit), 1.f);
  // Monotone in the raw confidence.
  EXPECT_LT(ConfidenceToUnit(1.0f), ConfidenceToUnit(1.1f));
}

TEST(Monst3rFrameList, Parses) {
  EXPECT_EQ(ParseFrameList("0..4", 25), (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_EQ(ParseFrameList("0..6:3,10", 25), (std::vector<int>{0, 3, 6, 10}));
  EXPECT_EQ(ParseFrameList("all", 3), (std::vector<int>{0, 1, 2}));
  ExpectInputError([] { ParseFrameList("0..25", 25); }, "out of range");
  ExpectInputError([] { ParseFrameList("a..b", 25); }, "cannot parse");
}

TEST(RawPointmap, ReadsXyzRgbAndConfidence) {
  const std::string dir = test::MakeTempDir("raw_pointmap");
  std::vector<float> data(2 * 3 * 6);
  for (size_t i = 0; i < data.size(); ++i)
    data[i] = (i % 6 < 3) ? i * 0.5f : 0.5f;
  WriteNpy(dir + "/p.npy", NpyArray::Float32({2, 3, 6}, data.data()));
  std::vector<float> conf = {3, 3, 1, 0.5f, 2, 3};
  WriteNpy(dir + "/c.npy", NpyArray::Float32({2, 3}, conf.data()));
  const RawPointmap raw =
      ReadRawPointmap(dir + "/p.npy", dir + "/c.npy", ConfidenceEncoding::kRaw);
  ASSERT_EQ(raw.points_in_world.size(), cv::Size(3, 2));
  EXPECT_FLOAT_EQ(raw.points_in_world.at<cv::Vec3f>(1, 2)[1],
                  (5 * 6 + 1) * 0.5f);
  EXPECT_EQ(raw.rgb.at<cv::Vec3b>(0, 0)[0], 128);
  EXPECT_NEAR(raw.confidence01.at<float>(0, 0), 2.0 / 3.0, 1e-6);
  EXPECT_EQ(raw.confidence01.at<float>(1, 0), 0.f);
  WriteNpy(dir + "/bad.npy", NpyArray::Float32({2, 3}, conf.data()));
  ExpectInputError([&] { ReadRawPointmap(dir + "/bad.npy"); }, "bad.npy");
}

}  // namespace
}  // namespace geodrive
