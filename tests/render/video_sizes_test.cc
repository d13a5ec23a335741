// Declared video sizes are checked before frames are decoded into memory
// (render/video/ffmpeg_decode.h, geometry/util/size_limits.h): frame counts
// over the limit, frames x size over the decode memory, frame sides over the
// limit in AVI and MP4 headers; and the streaming reader that compares long
// videos frame by frame holds one frame, not the video.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "geometry/util/size_limits.h"
#include "geometry/util/status.h"
#include "render/video/ffmpeg_decode.h"
#include "render/video/h264.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"

namespace geodrive {
// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder, whose anonymous helpers share names.
namespace video_sizes_test {

using ::testing::HasSubstr;

std::vector<cv::Mat> Frames(int n, int w, int h) {
  std::vector<cv::Mat> frames;
  for (int i = 0; i < n; ++i)
    frames.push_back(cv::Mat(h, w, CV_8UC3, cv::Scalar(10 * i, 80, 160)));
  return frames;
}

void Put32(std::string* s, size_t at, uint32_t v) {
  for (int k = 0; k < 4; ++k) (*s)[at + k] = static_cast<char>(v >> (8 * k));
}

std::string ErrorOf(const std::string& path) {
  try {
    ReadVideoFrames(path);
  } catch (const InputError& e) {
    std::cout << e.what() << "\n";
    return e.what();
  }
  return "";
}

// An MJPEG AVI of `n` frames of w x h whose headers declare `frames` frames
// (avih dwTotalFrames, strh dwLength) and, when given, frames of `side` x
// `side` (strf biWidth, biHeight).
std::string HostileAvi(
    const std::string& dir, int w, int h, uint32_t frames, uint32_t side = 0) {
  WriteVideoFrames(dir + "/small.avi", Frames(2, w, h), 10);
  std::string avi = test::ReadFile(dir + "/small.avi");
  const size_t avih = avi.find("avih");
  const size_t strh = avi.find("strh");
  const size_t strf = avi.find("strf");
  EXPECT_NE(avih, std::string::npos);
  Put32(&avi, avih + 8 + 16, frames);  // dwTotalFrames
  Put32(&avi, strh + 8 + 32, frames);  // dwLength
  if (side != 0) {
    Put32(&avi, strf + 12, side);
    Put32(&avi, strf + 16, side);
    Put32(&avi, avih + 8 + 32, side);  // dwWidth, dwHeight
    Put32(&avi, avih + 8 + 36, side);
  }
  return avi;
}

TEST(VideoSizes, DeclaredFrameCountsAndSizesAreCheckedBeforeDecoding) {
  const std::string dir = test::MakeTempDir("video_sizes");
  // 1. A million frames declared (the review's million 1x1 frames took
  // 1.4 GB): over the frame limit.
  test::WriteFile(dir + "/million.avi", HostileAvi(dir, 16, 16, 1000000));
  EXPECT_THAT(ErrorOf(dir + "/million.avi"),
              HasSubstr(dir + "/million.avi: the video declares 1000000, "
                              "over the limit of 100000"));
  // 2. 400 frames of 4000 x 4000: 19 GB decoded, over the decode memory.
  test::WriteFile(dir + "/memory.avi", HostileAvi(dir, 16, 16, 400, 4000));
  EXPECT_THAT(ErrorOf(dir + "/memory.avi"),
              HasSubstr(dir + "/memory.avi: 400 decoded frames of 4000x4000 "
                              "would need 19200409600 bytes, over the limit "
                              "of 17179869184 bytes"));
  // 3. Frames of 60000 x 60000 declared in the AVI's stream format.
  test::WriteFile(dir + "/side.avi", HostileAvi(dir, 16, 16, 2, 60000));
  EXPECT_THAT(ErrorOf(dir + "/side.avi"),
              HasSubstr(dir + "/side.avi: video frames of 60000x60000 pixels "
                              "are over the reader's limit"));
  // 4. An MP4 whose sample description declares 40000 x 40000 (16-bit
  // width and height of the 'avc1' entry).
  WriteH264Mp4(dir + "/good.mp4", Frames(3, 64, 48));
  std::string mp4 = test::ReadFile(dir + "/good.mp4");
  const size_t avc1 = mp4.find("avc1", mp4.find("stsd"));
  ASSERT_NE(avc1, std::string::npos);
  for (const size_t at : {avc1 + 28, avc1 + 30}) {
    mp4[at] = static_cast<char>(40000 >> 8);
    mp4[at + 1] = static_cast<char>(40000 & 0xff);
  }
  test::WriteFile(dir + "/side.mp4", mp4);
  const std::string e = ErrorOf(dir + "/side.mp4");
  EXPECT_THAT(e, HasSubstr(dir + "/side.mp4: "));
  EXPECT_THAT(e, HasSubstr("over the reader's limit"));
  // 5. The limits themselves: frames x size just over 16 GiB, and frames one
  // over the count.
  EXPECT_NO_THROW(CheckVideoFramesFit("v.mp4", 100000, 1, 1));
  EXPECT_THROW(CheckVideoFramesFit("v.mp4", 100001, 1, 1), InputError);
  EXPECT_THROW(CheckVideoFramesFit("v.mp4", 1000, 2400, 2400), InputError);
  // A real video still reads, whole and streamed, to the same frames.
  const std::vector<cv::Mat> whole = ReadVideoFrames(dir + "/good.mp4");
  VideoFrameStream stream(dir + "/good.mp4");
  cv::Mat frame;
  size_t n = 0;
  while (stream.Next(&frame)) {
    ASSERT_LT(n, whole.size());
    EXPECT_EQ(cv::norm(frame, whole[n], cv::NORM_INF), 0.0);
    ++n;
  }
  EXPECT_EQ(n, whole.size());
  EXPECT_EQ(stream.frames_read(), 3);
}

}  // namespace video_sizes_test
}  // namespace geodrive
