// ReadVideoFrames on video files: our FFmpeg reader (render/video/
// ffmpeg_decode.h), which the library uses instead of cv::VideoCapture.
//  - Round trips through our own writers: frame count exact, PSNR against the
//    raw frames at least the stated figure (lossless H.264: only the RGB ->
//    4:2:0 -> RGB conversion is lost).
//  - Frame-for-frame equality with cv2.VideoCapture (python3-opencv, the
//    reference reader) on the videos the tests and the builder
//    produce: H.264 (even and odd sizes), MPEG-4 'mp4v' in MP4 and Matroska,
//    MJPEG in AVI.
//  - Bad input: one InputError naming the file (missing, not a video,
//    truncated, corrupt, frames over the limits declared in the header).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "geometry/util/status.h"
#include "render/video/ffmpeg_decode.h"
#include "render/video/ffmpeg_encode.h"
#include "render/video/h264.h"
#include "render/video/video.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

// A moving scene with smooth gradients, hard edges and mild noise: what a
// render or a camera frame has.
std::vector<cv::Mat> MakeScene(int n, int w, int h) {
  std::vector<cv::Mat> frames;
  std::uniform_int_distribution<int> noise(-6, 6);
  for (int i = 0; i < n; ++i) {
    cv::Mat m(h, w, CV_8UC3);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const int r = 40 + 150 * x / w, g = 60 + 120 * y / h;
        const int b = 90 + 60 * ((x + 3 * i) % 40) / 40;
        m.at<cv::Vec3b>(y, x) =
            cv::Vec3b(cv::saturate_cast<uint8_t>(r + noise(test::Rng())),
                      cv::saturate_cast<uint8_t>(g + noise(test::Rng())),
                      cv::saturate_cast<uint8_t>(b + noise(test::Rng())));
      }
    }
    cv::rectangle(m, cv::Rect(5 + 2 * i, h / 3, w / 4, h / 3),
                  cv::Scalar(220, 30, 30), cv::FILLED);
    cv::circle(m, cv::Point(w - 20 - i, h / 2), h / 6, cv::Scalar(20, 200, 60),
               cv::FILLED);
    frames.push_back(m);
  }
  return frames;
}

double Psnr(const cv::Mat& a, const cv::Mat& b) {
  const double mse = cv::norm(a, b, cv::NORM_L2SQR) / (a.total() * 3.0);
  return mse == 0 ? 99.0 : 10 * std::log10(255.0 * 255.0 / mse);
}

double MinPsnr(const std::vector<cv::Mat>& got,
               const std::vector<cv::Mat>& want) {
  double min_psnr = 99;
  for (size_t i = 0; i < got.size() && i < want.size(); ++i)
    min_psnr = std::min(min_psnr, Psnr(got[i], want[i]));
  return min_psnr;
}

// The frames after the 4:2:0 conversion alone, done by OpenCV (RGB -> I420
// as the H.264 writer does, I420 -> RGB): what a lossless codec can give back
// at best. The saturated hard edges of MakeScene lose most to it.
std::vector<cv::Mat> Through420(const std::vector<cv::Mat>& frames) {
  std::vector<cv::Mat> out;
  for (const cv::Mat& f : frames) {
    cv::Mat yuv, rgb;
    cv::cvtColor(f, yuv, cv::COLOR_RGB2YUV_I420);
    cv::cvtColor(yuv, rgb, cv::COLOR_YUV2RGB_I420);
    out.push_back(rgb);
  }
  return out;
}

TEST(VideoReader, LosslessH264RoundTrip) {
  const std::string dir = test::MakeTempDir("video_reader_lossless");
  const std::vector<cv::Mat> frames = MakeScene(25, 160, 96);
  H264Options o;
  o.crf = 0;
  WriteH264Mp4(dir + "/lossless.mp4", frames, o);
  const std::vector<cv::Mat> back = ReadVideoFrames(dir + "/lossless.mp4");
  ASSERT_EQ(back.size(), 25u);
  ASSERT_EQ(back[0].type(), CV_8UC3);
  ASSERT_EQ(back[0].size(), cv::Size(160, 96));
  // All of the loss is the 4:2:0 conversion: against OpenCV's own 4:2:0
  // round trip only the two YUV -> RGB implementations differ (a level or
  // two).
  const double psnr = MinPsnr(back, frames);
  const double psnr420 = MinPsnr(back, Through420(frames));
  std::cout << "[video reader] lossless H.264: min PSNR " << psnr
            << " dB against the raw frames, " << psnr420
            << " dB against their 4:2:0 round trip (25 frames)\n";
  EXPECT_GE(psnr, 26.5);
  EXPECT_GE(psnr420, 40.0);
  // The same bytes decode to the same frames.
  const std::vector<cv::Mat> again = ReadVideoFrames(dir + "/lossless.mp4");
  for (size_t i = 0; i < back.size(); ++i)
    EXPECT_EQ(cv::norm(back[i], again[i], cv::NORM_INF), 0.0);
}

TEST(VideoReader, BuilderSizeH264RoundTrip) {
  // The builder's gt.mp4/cond.mp4: 720x480, CRF 18, 25 frames.
  const std::string dir = test::MakeTempDir("video_reader_crf18");
  const std::vector<cv::Mat> frames = MakeScene(25, 720, 480);
  WriteH264Mp4(dir + "/gt.mp4", frames);
  const std::vector<cv::Mat> back = ReadVideoFrames(dir + "/gt.mp4");
  ASSERT_EQ(back.size(), 25u);
  ASSERT_EQ(back[0].size(), cv::Size(720, 480));
  const double psnr = MinPsnr(back, frames);
  const double psnr420 = MinPsnr(back, Through420(frames));
  std::cout << "[video reader] H.264 CRF 18 720x480: min PSNR " << psnr
            << " dB against the raw frames, " << psnr420
            << " dB against their 4:2:0 round trip\n";
  EXPECT_GE(psnr, 30.0);
  EXPECT_GE(psnr420, 35.0);
}

TEST(VideoReader, OtherCodecsRoundTrip) {
  const std::string dir = test::MakeTempDir("video_reader_codecs");
  const std::vector<cv::Mat> frames = MakeScene(9, 64, 48);
  for (const std::string name : {"a.mp4", "b.avi"}) {
    WriteVideoFrames(dir + "/" + name, frames, 10);
    const std::vector<cv::Mat> back = ReadVideoFrames(dir + "/" + name);
    ASSERT_EQ(back.size(), 9u) << name;
    ASSERT_EQ(back[0].size(), cv::Size(64, 48)) << name;
    // Quantiser 2: as close to the raw frames as lossless H.264 (26.96 dB);
    // the loss is the 4:2:0 chroma of the saturated edges (swscale's bicubic
    // chroma filter, so OpenCV's box-filtered 4:2:0 is no closer).
    const double psnr = MinPsnr(back, frames);
    std::cout << "[video reader] " << name << ": min PSNR " << psnr
              << " dB against the raw frames\n";
    EXPECT_GE(psnr, 26.0) << name;
  }
}

// Frames as cv2.VideoCapture decodes them (tests/render/
// opencv_video_reference.py), or an empty vector with a test failure.
std::vector<cv::Mat> OpenCvFrames(const std::string& video) {
  const std::string raw = video + ".opencv.rgb";
  const std::string script = std::string(GEODRIVE_SOURCE_DIR) +
                             "/tests/render/opencv_video_reference.py";
  std::string out;
  const int rc = test::RunCommand(std::string(test::kDebianPython) + " " +
                                      script + " '" + video + "' '" + raw + "'",
                                  &out);
  EXPECT_EQ(rc, 0) << out;
  if (rc != 0) return {};
  int n = 0, h = 0, w = 0;
  std::istringstream(out) >> n >> h >> w;
  std::ifstream in(raw, std::ios::binary);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < n; ++i) {
    cv::Mat m(h, w, CV_8UC3);
    in.read(reinterpret_cast<char*>(m.data), m.total() * 3);
    frames.push_back(m);
  }
  EXPECT_TRUE(in.good()) << raw;
  return frames;
}

TEST(VideoReader, FramesEqualOpenCvVideoCapture) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("cv2");
  const std::string dir = test::MakeTempDir("video_reader_opencv");
  std::vector<std::string> videos;
  WriteH264Mp4(dir + "/h264.mp4", MakeScene(25, 720, 480));
  videos.push_back(dir + "/h264.mp4");
  WriteH264Mp4(dir + "/h264_odd.mp4", MakeScene(7, 99, 51));  // 100x52
  videos.push_back(dir + "/h264_odd.mp4");
  H264Options lossless;
  lossless.crf = 0;
  WriteH264Mp4(dir + "/h264_lossless.mp4", MakeScene(5, 160, 96), lossless);
  videos.push_back(dir + "/h264_lossless.mp4");
  VideoWriteOptions fallback;
  fallback.fourcc = "mp4v";
  WriteVideo(dir + "/mp4v.mp4", MakeScene(6, 66, 38), fallback);
  videos.push_back(dir + "/mp4v.mp4");
  WriteVideoFrames(dir + "/mjpeg.avi", MakeScene(4, 64, 48), 10);
  videos.push_back(dir + "/mjpeg.avi");
  {
    FfmpegVideoWriter mkv(dir + "/mp4v.mkv", 48, 32, "mp4v", 10);
    for (const cv::Mat& f : MakeScene(3, 48, 32)) mkv.Write(f);
    mkv.Finish();
  }
  videos.push_back(dir + "/mp4v.mkv");
  for (const std::string& video : videos) {
    const std::vector<cv::Mat> ours = ReadVideoFrames(video);
    const std::vector<cv::Mat> opencv = OpenCvFrames(video);
    ASSERT_EQ(ours.size(), opencv.size()) << video;
    double max_diff = 0;
    for (size_t i = 0; i < ours.size(); ++i) {
      ASSERT_EQ(ours[i].size(), opencv[i].size()) << video << " frame " << i;
      max_diff = std::max(max_diff, cv::norm(ours[i], opencv[i], cv::NORM_INF));
    }
    std::cout << "[video reader] " << std::filesystem::path(video).filename()
              << ": " << ours.size() << " frames " << ours[0].cols << "x"
              << ours[0].rows
              << ", max |ours - cv2.VideoCapture| = " << max_diff << "\n";
    EXPECT_EQ(max_diff, 0.0) << video;
  }
}

// ReadVideoFrames(path) throws one InputError that names the file and says
// `what`.
void ExpectRefused(const std::string& path, const std::string& what) {
  try {
    ReadVideoFrames(path);
    ADD_FAILURE() << path << " was read";
  } catch (const InputError& e) {
    const std::string message = e.what();
    std::cout << "[video reader] " << message << "\n";
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_NE(message.find(what), std::string::npos) << message;
  }
}

TEST(VideoReader, BadFilesAreOneInputErrorNamingTheFile) {
  const std::string dir = test::MakeTempDir("video_reader_bad");
  ExpectRefused(dir + "/missing.mp4", "no such file");
  test::WriteFile(dir + "/text.mp4", "this is not a video\n");
  ExpectRefused(dir + "/text.mp4", "not a readable video");
  test::WriteFile(dir + "/empty.mp4", "");
  ExpectRefused(dir + "/empty.mp4", "not a readable video");
  WriteH264Mp4(dir + "/good.mp4", MakeScene(25, 160, 96));
  const std::string good = test::ReadFile(dir + "/good.mp4");
  // Cut short: the index (moov first, faststart) points past the end.
  test::WriteFile(dir + "/truncated.mp4", good.substr(0, good.size() * 6 / 10));
  ExpectRefused(dir + "/truncated.mp4", "truncated");
  // Garbage over the middle of the coded frames.
  std::string corrupt = good;
  for (size_t i = corrupt.size() / 2; i < corrupt.size() / 2 + 400; ++i)
    corrupt[i] = static_cast<char>(0x5A ^ (i * 7));
  test::WriteFile(dir + "/corrupt.mp4", corrupt);
  ExpectRefused(dir + "/corrupt.mp4", "corrupt");
}

TEST(VideoReader, HugeFramesAreRefusedFromTheHeader) {
  // An AVI whose stream header declares 100000 x 100000 frames (biWidth and
  // biHeight of its 'strf' chunk): refused before any frame is decoded.
  const std::string dir = test::MakeTempDir("video_reader_huge");
  WriteVideoFrames(dir + "/small.avi", MakeScene(2, 64, 48), 10);
  std::string avi = test::ReadFile(dir + "/small.avi");
  const size_t strf = avi.find("strf");
  ASSERT_NE(strf, std::string::npos);
  for (const size_t at : {strf + 12, strf + 16}) {  // biWidth, biHeight
    const uint32_t v = 100000;
    for (int k = 0; k < 4; ++k) avi[at + k] = static_cast<char>(v >> (8 * k));
  }
  test::WriteFile(dir + "/huge.avi", avi);
  ExpectRefused(dir + "/huge.avi", "over the reader's limit");
}

}  // namespace
}  // namespace geodrive
