#include "dataset/internal/pair_png.h"

#include <spng.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <zlib.h>

#include <array>
#include <cstdlib>
#include <memory>
#include <vector>

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

namespace {

// Encodes `rows` (packed as `ihdr` says) with the pair's PNG settings;
// `path` names the file in errors.
std::string EncodePng(const std::string& path,
                      const spng_ihdr& ihdr,
                      const void* rows,
                      size_t bytes,
                      int filter) {
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
  check(spng_set_option(ctx.get(), SPNG_FILTER_CHOICE, filter));
  spng_ihdr header = ihdr;
  check(spng_set_ihdr(ctx.get(), &header));
  check(spng_encode_image(ctx.get(), rows, bytes, SPNG_FMT_PNG,
                          SPNG_ENCODE_FINALIZE));
  size_t size = 0;
  int err = 0;
  std::unique_ptr<void, SpngFree> png(
      spng_get_png_buffer(ctx.get(), &size, &err));
  check(err);
  GEODRIVE_CHECK_INPUT(png != nullptr, path, ": libspng returned no PNG");
  return std::string(static_cast<const char*>(png.get()), size);
}

#if defined(__SSE2__)
// kReversedBits[b]: b with its bit order reversed (bit 0 <-> bit 7).
constexpr std::array<uint8_t, 256> ReversedBitsTable() {
  std::array<uint8_t, 256> table{};
  for (int b = 0; b < 256; ++b) {
    int r = 0;
    for (int i = 0; i < 8; ++i) r |= ((b >> i) & 1) << (7 - i);
    table[b] = static_cast<uint8_t>(r);
  }
  return table;
}
constexpr std::array<uint8_t, 256> kReversedBits = ReversedBitsTable();
#endif

}  // namespace

void WritePairPng(const std::string& path,
                  const cv::Mat& rgb,
                  PngContent content) {
  GEODRIVE_CHECK_INPUT(
      !rgb.empty() && (rgb.type() == CV_8UC3 || rgb.type() == CV_8UC1), path,
      ": expected a non-empty RGB (CV_8UC3) or gray (CV_8UC1) image");
  const cv::Mat data = rgb.isContinuous() ? rgb : rgb.clone();
  spng_ihdr ihdr{};
  ihdr.width = static_cast<uint32_t>(data.cols);
  ihdr.height = static_cast<uint32_t>(data.rows);
  ihdr.bit_depth = 8;
  ihdr.color_type = data.channels() == 3 ? SPNG_COLOR_TYPE_TRUECOLOR
                                         : SPNG_COLOR_TYPE_GRAYSCALE;
  WriteFileAtomic(
      path, EncodePng(path, ihdr, data.data, data.total() * data.elemSize(),
                      content == PngContent::kPhoto ? SPNG_FILTER_CHOICE_PAETH
                                                    : SPNG_DISABLE_FILTERING));
}

void WriteMaskPng(const std::string& path, const cv::Mat& mask) {
  WriteFileAtomic(path, EncodeMaskPng(path, mask));
}

std::string EncodeMaskPng(const std::string& path, const cv::Mat& mask) {
  GEODRIVE_CHECK_INPUT(!mask.empty() && mask.type() == CV_8UC1, path,
                       ": expected a non-empty mask (CV_8UC1)");
  const int w = mask.cols, stride = (w + 7) / 8;
  std::vector<uint8_t> rows(static_cast<size_t>(stride) * mask.rows, 0);
  for (int y = 0; y < mask.rows; ++y) {
    const uint8_t* in = mask.ptr<uint8_t>(y);
    uint8_t* out = &rows[static_cast<size_t>(y) * stride];
    // Most significant bit first (PNG).
    int x = 0;
#if defined(__SSE2__)
    // Sixteen pixels at a time: movemask gives one bit a pixel, least
    // significant first; a table reverses the bits of each byte.
    const __m128i zero = _mm_setzero_si128();
    for (; x + 16 <= w; x += 16) {
      const __m128i v =
          _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + x));
      const int set = ~_mm_movemask_epi8(_mm_cmpeq_epi8(v, zero)) & 0xffff;
      out[x >> 3] = kReversedBits[set & 0xff];
      out[(x >> 3) + 1] = kReversedBits[set >> 8];
    }
#endif
    for (; x + 8 <= w; x += 8) {  // eight pixels a byte, unrolled
      const uint8_t* p = in + x;
      out[x >> 3] = static_cast<uint8_t>((p[0] != 0) << 7 | (p[1] != 0) << 6 |
                                         (p[2] != 0) << 5 | (p[3] != 0) << 4 |
                                         (p[4] != 0) << 3 | (p[5] != 0) << 2 |
                                         (p[6] != 0) << 1 | (p[7] != 0));
    }
    for (; x < w; ++x)
      out[x >> 3] |= static_cast<uint8_t>((in[x] != 0) << (7 - (x & 7)));
  }
  spng_ihdr ihdr{};
  ihdr.width = static_cast<uint32_t>(w);
  ihdr.height = static_cast<uint32_t>(mask.rows);
  ihdr.bit_depth = 1;
  ihdr.color_type = SPNG_COLOR_TYPE_GRAYSCALE;
  // Filters gain nothing on runs of whole bytes; none is the fastest.
  return EncodePng(path, ihdr, rows.data(), rows.size(),
                   SPNG_DISABLE_FILTERING);
}

}  // namespace internal
}  // namespace geodrive
