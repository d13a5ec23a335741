// `geodrive eval` end to end: pairs folders, outputs, bad input and the
// no-LibTorch message.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "eval/deep_metrics.h"
#include "eval/image_metrics.h"
#include "geometry/trajectory_io.h"
#include "geometry/util/status.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace eval_cli_test {
namespace {

std::vector<cv::Mat> MakeClip(int frames, uint32_t seed, int noise) {
  std::mt19937 rng(seed);
  std::vector<cv::Mat> out;
  cv::Mat base(48, 64, CV_8UC3);
  cv::randu(base, 0, 256);
  cv::GaussianBlur(base, base, cv::Size(0, 0), 1.5);
  for (int i = 0; i < frames; ++i) {
    cv::Mat f = base.clone();
    for (size_t k = 0; k < f.total() * 3; ++k) {
      const int v =
          f.data[k] + static_cast<int>(rng() % (2 * noise + 1)) - noise + i;
      f.data[k] = static_cast<uint8_t>(std::clamp(v, 0, 255));
    }
    out.push_back(f);
  }
  return out;
}

TEST(EvalCli, PairsFoldersReportAndFiles) {
  const std::string dir = test::MakeTempDir("eval_cli_pairs");
  std::vector<std::vector<cv::Mat>> gts, preds;
  for (int c = 0; c < 2; ++c) {
    gts.push_back(MakeClip(5, 10 + c, 0));
    preds.push_back(MakeClip(5, 10 + c, 6 + 10 * c));
    const std::string clip = dir + "/pairs/clip_" + std::to_string(c);
    WriteVideoFrames(clip + "/gt", gts.back());  // frame folders: lossless
    WriteVideoFrames(clip + "/pred", preds.back());
  }
  Trajectory gt_traj, pred_traj;
  for (int i = 0; i < 5; ++i) {
    gt_traj.Add(
        i, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, i)));
    pred_traj.Add(i, Rigid3d(Eigen::Quaterniond::Identity(),
                             Eigen::Vector3d(0.01 * i, 0, i)));
  }
  WriteTumTrajectory(dir + "/gt.txt", gt_traj);
  WriteTumTrajectory(dir + "/pred.txt", pred_traj);
  int rc = 0;
  const std::string out = test::RunGeodriveEval(
      "--pred " + dir + "/pairs --gt " + dir +
          "/pairs --metrics psnr,ssim,ade,fde --x100 --pred-traj " + dir +
          "/pred.txt --gt-traj " + dir + "/gt.txt --out " + dir +
          "/out/report.json",
      &rc);
  ASSERT_EQ(rc, 0) << out;
  for (const char* ext : {".json", ".csv", ".md", ".png"}) {
    EXPECT_TRUE(std::filesystem::exists(dir + "/out/report" + std::string(ext)))
        << ext;
  }
  std::ifstream in(dir + "/out/report.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  ASSERT_EQ(j["videos"].size(), 2u);
  double psnr_mean = 0;
  for (int c = 0; c < 2; ++c) {
    const VideoScores s = CompareVideos(preds[c], gts[c]);
    EXPECT_NEAR(j["videos"][c]["psnr"].get<double>(), s.mean.psnr_rgb, 1e-9);
    EXPECT_NEAR(j["videos"][c]["ssim"].get<double>(), s.mean.ssim_rgb, 1e-12);
    psnr_mean += s.mean.psnr_rgb / 2;
  }
  EXPECT_NEAR(j["summary"]["psnr"]["mean"].get<double>(), psnr_mean, 1e-9);
  // ADE x 100 of offsets 0.01 i, i = 0..4: mean 0.02 -> 2; FDE 0.04 -> 4.
  EXPECT_NEAR(j["trajectory"]["ade"].get<double>(), 2.0, 1e-9);
  EXPECT_NEAR(j["trajectory"]["fde"].get<double>(), 4.0, 1e-9);
  std::ifstream md(dir + "/out/report.md");
  std::string header;
  std::getline(md, header);
  EXPECT_EQ(
      header,
      "| Model | LPIPS↓ | PSNR↑ | SSIM↑ | FID↓ | FVD↓ | ADE×10²↓ | FDE×10²↓ |");
}

TEST(EvalCli, Mp4Input) {
  const std::string dir = test::MakeTempDir("eval_cli_mp4");
  const auto gt = MakeClip(6, 3, 0);
  WriteVideoFrames(dir + "/gt.mp4", gt);
  const auto frames = ReadVideoFrames(dir + "/gt.mp4");
  ASSERT_EQ(frames.size(), 6u);
  EXPECT_GT(Psnr(frames[0], gt[0]), 25.0);  // lossy codec, but the same picture
  int rc = 0;
  const std::string out =
      test::RunGeodriveEval("--pred " + dir + "/gt.mp4 --gt " + dir +
                                "/gt.mp4 --out " + dir + "/r.json",
                            &rc);
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("psnr 100"), std::string::npos)
      << out;  // identical -> cap
}

TEST(EvalCli, BadInputExitsTwoWithOneLine) {
  const std::string dir = test::MakeTempDir("eval_cli_bad");
  WriteVideoFrames(dir + "/gt", MakeClip(5, 1, 0));
  WriteVideoFrames(dir + "/pred", MakeClip(4, 1, 3));
  std::filesystem::create_directories(dir + "/empty");
  int rc = 0;
  std::string out = test::RunGeodriveEval(
      "--pred " + dir + "/pred --gt " + dir + "/gt --out " + dir + "/r.json",
      &rc);
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("frame counts differ (predicted 4, ground truth 5)"),
            std::string::npos)
      << out;
  out = test::RunGeodriveEval(
      "--pred " + dir + "/empty --gt " + dir + "/gt --out " + dir + "/r.json",
      &rc);
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("no videos found"), std::string::npos) << out;
  out = test::RunGeodriveEval("--pred " + dir + "/pred --gt " + dir +
                                  "/gt --metrics psnr,fid --out " + dir +
                                  "/r.json",
                              &rc);
  EXPECT_EQ(rc, 2);
  // Without LibTorch: the build cannot; with it: the model flag is missing
  // (deep_metrics_test.cc covers the LibTorch build further).
  EXPECT_NE(out.find(DeepMetricsAvailable()
                         ? "--metrics fid needs --fid-model"
                         : "lpips/fid/fvd need a build with "
                           "GEODRIVE_WITH_TORCH=ON and a TorchScript model"),
            std::string::npos)
      << out;
  // Trajectories of different lengths.
  Trajectory a, b;
  for (int i = 0; i < 4; ++i) a.Add(i, Rigid3d());
  for (int i = 0; i < 3; ++i) b.Add(i, Rigid3d());
  WriteTumTrajectory(dir + "/a.txt", a);
  WriteTumTrajectory(dir + "/b.txt", b);
  out = test::RunGeodriveEval("--metrics ade,fde --pred-traj " + dir +
                                  "/a.txt --gt-traj " + dir + "/b.txt --out " +
                                  dir + "/r.json",
                              &rc);
  EXPECT_EQ(rc, 2);
  EXPECT_NE(out.find("differ in length (predicted 4 poses, ground truth 3)"),
            std::string::npos)
      << out;
}

}  // namespace
}  // namespace eval_cli_test
}  // namespace geodrive
