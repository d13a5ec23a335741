#include "geometry/exr.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>

#include <exception>

#include "geometry/util/input_file.h"
#include "geometry/util/status.h"

namespace geodrive {

std::vector<std::string> ExrChannels(const std::string& path) {
  CheckInputFile(path);  // OpenEXR opens the path itself
  try {
    Imf::InputFile file(path.c_str());
    std::vector<std::string> names;
    for (auto it = file.header().channels().begin();
         it != file.header().channels().end(); ++it)
      names.push_back(it.name());
    return names;
  } catch (const std::exception& e) {
    ThrowInputError(path, "not a readable EXR file: ", e.what());
  }
}

cv::Mat ReadExr(const std::string& path,
                const std::vector<std::string>& channels) {
  GEODRIVE_CHECK_INPUT(!channels.empty() && channels.size() <= 4, path,
                       ": read 1 to 4 channels");
  CheckInputFile(path);
  try {
    Imf::InputFile file(path.c_str());
    const Imath::Box2i dw = file.header().dataWindow();
    const int64_t w = int64_t(dw.max.x) - dw.min.x + 1;
    const int64_t h = int64_t(dw.max.y) - dw.min.y + 1;
    GEODRIVE_CHECK_INPUT(w >= 1 && h >= 1 && w <= 16384 && h <= 16384, path,
                         ": data window ", w, "x", h,
                         " is outside 1..16384 a side");
    std::string have;
    for (auto it = file.header().channels().begin();
         it != file.header().channels().end(); ++it)
      have += std::string(have.empty() ? "" : ", ") + it.name();
    const int n = static_cast<int>(channels.size());
    cv::Mat image(static_cast<int>(h), static_cast<int>(w), CV_32FC(n),
                  cv::Scalar::all(0));
    Imf::FrameBuffer fb;
    const size_t xs = sizeof(float) * n, ys = xs * w;
    // The slice base points at pixel (0, 0) of the file's coordinates.
    char* base = reinterpret_cast<char*>(image.ptr<float>()) -
                 int64_t(dw.min.x) * int64_t(xs) -
                 int64_t(dw.min.y) * int64_t(ys);
    for (int k = 0; k < n; ++k) {
      GEODRIVE_CHECK_INPUT(
          file.header().channels().findChannel(channels[k].c_str()), path,
          ": no channel '", channels[k], "' (the file has ", have, ")");
      fb.insert(channels[k].c_str(),
                Imf::Slice(Imf::FLOAT, base + k * sizeof(float), xs, ys));
    }
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    return image;
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    ThrowInputError(path, "cannot read the EXR image: ", e.what());
  }
}

void WriteExr(const std::string& path,
              const cv::Mat& image,
              const std::vector<std::string>& channels) {
  GEODRIVE_CHECK_INPUT(
      image.depth() == CV_32F &&
          image.channels() == static_cast<int>(channels.size()),
      path,
      ": WriteExr needs a CV_32F image with one name per "
      "channel");
  const cv::Mat m = image.isContinuous() ? image : image.clone();
  try {
    Imf::Header header(m.cols, m.rows);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const std::string& c : channels)
      header.channels().insert(c.c_str(), Imf::Channel(Imf::FLOAT));
    Imf::OutputFile file(path.c_str(), header);
    Imf::FrameBuffer fb;
    const size_t xs = sizeof(float) * channels.size(), ys = xs * m.cols;
    char* base =
        const_cast<char*>(reinterpret_cast<const char*>(m.ptr<float>()));
    for (size_t k = 0; k < channels.size(); ++k)
      fb.insert(channels[k].c_str(),
                Imf::Slice(Imf::FLOAT, base + k * sizeof(float), xs, ys));
    file.setFrameBuffer(fb);
    file.writePixels(m.rows);
  } catch (const std::exception& e) {
    ThrowInputError(path, "cannot write the EXR image: ", e.what());
  }
}

}  // namespace geodrive
