#include "dataset/internal/pair_png.h"

#include <spng.h>
#include <zlib.h>

#include <cstdlib>
#include <memory>

#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace internal {
namespace {

struct SpngFree {
  void operator()(spng_ctx* ctx) const { spng_ctx_free(ctx); }
  void operator()(void* p) const { std::free(p); }
};

}  // namespace

void WritePairPng(const std::string& path, const cv::Mat& rgb) {
  GEODRIVE_CHECK_INPUT(
      !rgb.empty() && (rgb.type() == CV_8UC3 || rgb.type() == CV_8UC1), path,
      ": expected a non-empty RGB (CV_8UC3) or gray (CV_8UC1) image");
  const cv::Mat data = rgb.isContinuous() ? rgb : rgb.clone();
  std::unique_ptr<spng_ctx, SpngFree> ctx(spng_ctx_new(SPNG_CTX_ENCODER));
  GEODRIVE_CHECK_INPUT(ctx != nullptr, path,
                       ": cannot start libspng (out of memory)");
  auto check = [&](int err) {
    GEODRIVE_CHECK_INPUT(err == 0, path,
                         ": cannot encode PNG (libspng: ", spng_strerror(err),
                         ")");
  };
  check(spng_set_option(ctx.get(), SPNG_ENCODE_TO_BUFFER, 1));
  check(spng_set_option(ctx.get(), SPNG_IMG_COMPRESSION_LEVEL, 1));
  check(spng_set_option(ctx.get(), SPNG_IMG_COMPRESSION_STRATEGY, Z_RLE));
  check(
      spng_set_option(ctx.get(), SPNG_FILTER_CHOICE, SPNG_FILTER_CHOICE_PAETH));
  spng_ihdr ihdr{};
  ihdr.width = static_cast<uint32_t>(data.cols);
  ihdr.height = static_cast<uint32_t>(data.rows);
  ihdr.bit_depth = 8;
  ihdr.color_type = data.channels() == 3 ? SPNG_COLOR_TYPE_TRUECOLOR
                                         : SPNG_COLOR_TYPE_GRAYSCALE;
  check(spng_set_ihdr(ctx.get(), &ihdr));
  check(spng_encode_image(ctx.get(), data.data, data.total() * data.elemSize(),
                          SPNG_FMT_PNG, SPNG_ENCODE_FINALIZE));
  size_t size = 0;
  int err = 0;
  std::unique_ptr<void, SpngFree> png(
      spng_get_png_buffer(ctx.get(), &size, &err));
  check(err);
  GEODRIVE_CHECK_INPUT(png != nullptr, path, ": libspng returned no PNG");
  WriteFileAtomic(path, png.get(), size);
}

}  // namespace internal
}  // namespace geodrive
