#include "geometry/image_io.h"

#include <spng.h>
#include <turbojpeg.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

constexpr uint64_t kMaxImageFileBytes = 1ull << 31;  // 2 GiB
// Ancillary PNG chunks (text, ICC profile, EXIF) kept in memory while reading.
constexpr size_t kMaxPngChunkBytes = size_t{64} << 20;

// What the caller wants, as OpenCV's imread flags: IMREAD_COLOR (8-bit, 3
// channels), IMREAD_GRAYSCALE (8-bit, 1 channel) or IMREAD_UNCHANGED (the
// file's depth and channels, BGR/BGRA order, no EXIF orientation).
enum class Mode { kColor, kGray, kUnchanged };

struct Request {
  Mode mode = Mode::kColor;
  bool rgb = false;  // kColor: RGB order instead of OpenCV's BGR
  JpegScale scale;   // JPEG only: decode at scale.num / scale.denom
};

bool IsJpeg(const std::vector<uint8_t>& b) {
  return b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF;
}
bool IsPng(const std::vector<uint8_t>& b) {
  static const uint8_t kSig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  return b.size() >= 8 && std::memcmp(b.data(), kSig, 8) == 0;
}

uint32_t Be32(const uint8_t* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) |
         (uint32_t{p[2]} << 8) | uint32_t{p[3]};
}

// Refuses an image over ImageReadLimits, before anything is allocated.
void CheckLimits(const std::string& path, uint64_t width, uint64_t height) {
  if (width == 0 || height == 0) {
    ThrowInputError(path, "image header declares an empty image (", width, "x",
                    height, ")");
  }
  if (width > uint64_t{ImageReadLimits::kMaxSide} ||
      height > uint64_t{ImageReadLimits::kMaxSide} ||
      width * height > uint64_t(ImageReadLimits::kMaxPixels)) {
    ThrowInputError(path, "image of ", width, "x", height,
                    " pixels is over the reader's limit (",
                    ImageReadLimits::kMaxSide, " pixels per side, ",
                    ImageReadLimits::kMaxPixels, " pixels)");
  }
}

// A library message on one line.
std::string OneLine(const char* message) {
  std::string s = message ? message : "unknown error";
  for (char& c : s) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

// ---- EXIF orientation ----

// The EXIF orientation tag (1..8) of a TIFF structure, 1 when absent. Parses
// IFD0 exactly as OpenCV 4.6's ExifReader does (so that images come out as
// cv::imdecode rotates them): byte order "II" or else big-endian, tag mark
// 0x2A, entries read in order until one reaches past the data (entries read
// before that count), the first orientation entry wins, its value is the
// 16-bit word at offset 8 of the entry whatever its declared type. Every read
// is bounds-checked.
int ExifOrientation(const uint8_t* d, size_t n) {
  if (d == nullptr || n == 0) return 1;
  const bool intel = !(n > 1 && d[0] != d[1]) && d[0] == 'I';
  auto u16 = [&](uint64_t o, uint32_t* v) {
    if (o + 1 >= n) return false;
    *v = intel ? d[o] | (d[o + 1] << 8) : (d[o] << 8) | d[o + 1];
    return true;
  };
  auto u32 = [&](uint64_t o, uint32_t* v) {
    if (o + 3 >= n) return false;
    *v = intel ? uint32_t{d[o]} | (uint32_t{d[o + 1]} << 8) |
                     (uint32_t{d[o + 2]} << 16) | (uint32_t{d[o + 3]} << 24)
               : Be32(d + o);
    return true;
  };
  uint32_t mark = 0, ifd = 0, count = 0;
  if (!u16(2, &mark) || mark != 0x2A || !u32(4, &ifd) || !u16(ifd, &count)) {
    return 1;
  }
  int orientation = 1;
  bool found = false;
  uint64_t entry = uint64_t{ifd} + 2;
  uint32_t v = 0, w = 0;
  for (uint32_t i = 0; i < count; ++i, entry += 12) {
    if (!u16(entry, &v)) break;
    const uint32_t tag = v;
    int rationals = 0;  // tags whose value OpenCV reads as unsigned rationals
    switch (tag) {
      case 0x0112:  // Orientation
        if (!u16(entry + 8, &v)) return orientation;
        if (!found) orientation = static_cast<int>(v);
        found = true;
        continue;
      case 0x0128:  // ResolutionUnit
      case 0x0213:  // YCbCrPositioning
        if (!u16(entry + 8, &v)) return orientation;
        continue;
      case 0x010E:  // strings: ImageDescription, Make, Model, Software,
      case 0x010F:  // DateTime, Copyright
      case 0x0110:
      case 0x0131:
      case 0x0132:
      case 0x8298: {
        if (!u32(entry + 4, &v)) return orientation;
        uint64_t data = 8;
        if (v > 4) {
          if (!u32(entry + 8, &w)) return orientation;
          data = w;
        }
        if (data > n || data + v > n) return orientation;
        continue;
      }
      case 0x011A:  // XResolution
      case 0x011B:  // YResolution
        rationals = 1;
        break;
      case 0x013E:  // WhitePoint
        rationals = 2;
        break;
      case 0x0211:  // YCbCrCoefficients
        rationals = 3;
        break;
      case 0x013F:  // PrimaryChromaticities
      case 0x0214:  // ReferenceBlackWhite
        rationals = 6;
        break;
      default:
        continue;
    }
    if (!u32(entry + 8, &w)) return orientation;
    for (int k = 0; k < rationals; ++k) {
      if (!u32(uint64_t{w} + 8 * k, &v) || !u32(uint64_t{w} + 8 * k + 4, &v)) {
        return orientation;
      }
    }
  }
  return orientation;
}

// Rotates/flips a decoded image by an EXIF orientation as OpenCV's
// ApplyExifOrientation does.
void ApplyOrientation(int orientation, cv::Mat* image) {
  switch (orientation) {
    case 2:
      cv::flip(*image, *image, 1);
      break;
    case 3:
      cv::flip(*image, *image, -1);
      break;
    case 4:
      cv::flip(*image, *image, 0);
      break;
    case 5:
      cv::transpose(*image, *image);
      break;
    case 6:
      cv::transpose(*image, *image);
      cv::flip(*image, *image, 1);
      break;
    case 7:
      cv::transpose(*image, *image);
      cv::flip(*image, *image, -1);
      break;
    case 8:
      cv::transpose(*image, *image);
      cv::flip(*image, *image, 0);
      break;
    default:  // 1 and invalid values: as stored
      break;
  }
}

bool SwapsSides(int orientation) {
  return orientation >= 5 && orientation <= 8;
}

// ---- JPEG ----

struct JpegScan {
  bool complete = false;  // reached the EOI marker
  int width = 0, height = 0;
  // The first APP1 segment before the first scan (OpenCV takes its EXIF from
  // it, whatever its identifier).
  const uint8_t* app1 = nullptr;
  size_t app1_size = 0;
};

// Walks the JPEG marker structure (segments, then entropy-coded scans) up to
// EOI. libjpeg only warns on a truncated file; this makes truncation an error
// with a clear message before the decoder runs.
JpegScan ScanJpeg(const std::vector<uint8_t>& b) {
  JpegScan scan;
  size_t i = 2;  // after SOI
  const size_t n = b.size();
  bool seen_sos = false;
  while (i + 1 < n) {
    if (b[i] != 0xFF) return scan;  // corrupt
    uint8_t marker = b[i + 1];
    if (marker == 0xFF) {  // fill byte
      ++i;
      continue;
    }
    i += 2;
    if (marker == 0xD9) {
      scan.complete = true;
      return scan;
    }
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7))
      continue;  // no length
    if (i + 1 >= n) return scan;
    const size_t length = (size_t{b[i]} << 8) | b[i + 1];
    if (length < 2 || i + length > n) return scan;
    const bool is_sof = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 &&
                        marker != 0xC8 && marker != 0xCC;
    if (is_sof && length >= 7 && scan.width == 0) {
      scan.height = (b[i + 3] << 8) | b[i + 4];
      scan.width = (b[i + 5] << 8) | b[i + 6];
    }
    if (marker == 0xE1 && !seen_sos && scan.app1 == nullptr) {
      scan.app1 = &b[i + 2];
      scan.app1_size = length - 2;
    }
    i += length;
    if (marker == 0xDA) {
      seen_sos = true;
      // Entropy-coded data: ends at the first marker that is not a stuffed
      // 0xFF00 or RSTn. memchr jumps from one 0xFF to the next (a byte loop
      // here cost 0.4 ms a 1600x900 frame, most of a header read).
      while (i + 1 < n) {
        const void* ff = std::memchr(&b[i], 0xFF, n - 1 - i);
        if (ff == nullptr) {
          i = n - 1;
          break;
        }
        i = static_cast<size_t>(static_cast<const uint8_t*>(ff) - b.data());
        if (b[i + 1] != 0x00 && !(b[i + 1] >= 0xD0 && b[i + 1] <= 0xD7)) break;
        ++i;
      }
    }
  }
  return scan;
}

int JpegOrientation(const JpegScan& scan) {
  constexpr size_t kTiffOffset = 6;  // "Exif\0\0"
  if (scan.app1 == nullptr || scan.app1_size <= kTiffOffset) return 1;
  return ExifOrientation(scan.app1 + kTiffOffset, scan.app1_size - kTiffOffset);
}

struct TjDeleter {
  void operator()(void* handle) const { tjDestroy(handle); }
};
using TjHandle = std::unique_ptr<void, TjDeleter>;

TjHandle NewTjHandle(const std::string& path, bool decompress) {
  TjHandle handle(decompress ? tjInitDecompress() : tjInitCompress());
  if (!handle) {
    ThrowInputError(path, "cannot start libjpeg-turbo (",
                    OneLine(tjGetErrorStr2(nullptr)), ")");
  }
  return handle;
}

struct JpegHeader {
  int width = 0, height = 0;
  int colorspace = -1;  // TJCS_*
};

// Reads the JPEG header (no pixel memory) and checks the limits.
JpegHeader ReadJpegHeader(const std::string& path,
                          tjhandle tj,
                          const std::vector<uint8_t>& bytes) {
  JpegHeader h;
  int subsampling = -1;
  const int rc = tjDecompressHeader3(tj, bytes.data(), bytes.size(), &h.width,
                                     &h.height, &subsampling, &h.colorspace);
  if (rc != 0) {
    // libjpeg-turbo 2.1 also refuses headers whose chroma subsampling has no
    // TurboJPEG name (width and height are read by then); libjpeg decodes
    // those, as OpenCV does.
    const bool warning = tjGetErrorCode(tj) == TJERR_WARNING;
    if (warning || h.width <= 0 || h.height <= 0 || subsampling >= 0) {
      ThrowInputError(path,
                      warning ? "corrupt JPEG header (libjpeg warning: "
                              : "not a readable JPEG (libjpeg: ",
                      OneLine(tjGetErrorStr2(tj)), ")");
    }
  }
  if (h.width <= 0 || h.height <= 0)
    ThrowInputError(path, "not a readable JPEG (no image in the data stream)");
  CheckLimits(path, h.width, h.height);
  return h;
}

// OpenCV's CMYK conversions (icvCvt_CMYK2BGR_8u_C4C3R and
// icvCvt_CMYK2Gray_8u_C4C1R), so that CMYK/YCCK JPEGs decode as cv::imdecode
// decodes them.
void CmykToColor(const cv::Mat& cmyk, bool rgb, cv::Mat* out) {
  out->create(cmyk.size(), CV_8UC3);
  for (int y = 0; y < cmyk.rows; ++y) {
    const uint8_t* s = cmyk.ptr<uint8_t>(y);
    uint8_t* d = out->ptr<uint8_t>(y);
    for (int x = 0; x < cmyk.cols; ++x, s += 4, d += 3) {
      const int k = s[3];
      const int c = k - ((255 - s[0]) * k >> 8);
      const int m = k - ((255 - s[1]) * k >> 8);
      const int ye = k - ((255 - s[2]) * k >> 8);
      d[rgb ? 0 : 2] = static_cast<uint8_t>(c);
      d[1] = static_cast<uint8_t>(m);
      d[rgb ? 2 : 0] = static_cast<uint8_t>(ye);
    }
  }
}

void CmykToGray(const cv::Mat& cmyk, cv::Mat* out) {
  constexpr int kR = 4899, kG = 9617, kB = 16384 - kR - kG;  // 0.299, 0.587
  out->create(cmyk.size(), CV_8UC1);
  for (int y = 0; y < cmyk.rows; ++y) {
    const uint8_t* s = cmyk.ptr<uint8_t>(y);
    uint8_t* d = out->ptr<uint8_t>(y);
    for (int x = 0; x < cmyk.cols; ++x, s += 4) {
      const int k = s[3];
      const int c = k - ((255 - s[0]) * k >> 8);
      const int m = k - ((255 - s[1]) * k >> 8);
      const int ye = k - ((255 - s[2]) * k >> 8);
      d[x] = static_cast<uint8_t>((ye * kB + m * kG + c * kR + 8192) >> 14);
    }
  }
}

bool SameScale(const tjscalingfactor& a, const tjscalingfactor& b) {
  return a.num * b.denom == b.num * a.denom;
}

// Whether tjDecompress2 would decode a width x height JPEG at exactly `want`
// when asked for its output size (it takes the first, largest, factor in its
// list whose output fits; a larger factor with the same rounded size wins).
bool TjPicksScale(int width, int height, const tjscalingfactor& want) {
  int count = 0;
  const tjscalingfactor* factors = tjGetScalingFactors(&count);
  if (factors == nullptr) return want.num == want.denom;
  const int w = TJSCALED(width, want), h = TJSCALED(height, want);
  for (int i = 0; i < count; ++i) {
    if (TJSCALED(width, factors[i]) <= w && TJSCALED(height, factors[i]) <= h)
      return SameScale(factors[i], want);
  }
  return false;
}

cv::Mat DecodeJpeg(const std::string& path,
                   const std::vector<uint8_t>& bytes,
                   const Request& request) {
  const JpegScan scan = ScanJpeg(bytes);
  if (!scan.complete)
    ThrowInputError(path, "truncated or corrupt JPEG (no end-of-image marker)");
  TjHandle tj = NewTjHandle(path, /*decompress=*/true);
  const JpegHeader header = ReadJpegHeader(path, tj.get(), bytes);
  const bool cmyk =
      header.colorspace == TJCS_CMYK || header.colorspace == TJCS_YCCK;
  const bool gray_file = header.colorspace == TJCS_GRAY;
  // cv::imdecode's output: IMREAD_UNCHANGED keeps gray files gray, any other
  // (colour or CMYK) file becomes BGR.
  const bool gray_out = request.mode == Mode::kGray ||
                        (request.mode == Mode::kUnchanged && gray_file);
  const bool rgb = request.mode == Mode::kColor && request.rgb;
  int pixel_format = gray_out ? TJPF_GRAY : rgb ? TJPF_RGB : TJPF_BGR;
  if (cmyk) pixel_format = TJPF_CMYK;

  const tjscalingfactor factor{request.scale.num, request.scale.denom};
  const int width = TJSCALED(header.width, factor);
  const int height = TJSCALED(header.height, factor);
  cv::Mat decoded(height, width, CV_8UC(tjPixelSize[pixel_format]));
  // Default IDCT (JDCT_ISLOW) and fancy upsampling, as OpenCV's decoder; any
  // libjpeg warning (corrupt or missing entropy data) stops the decode.
  const int flags = TJFLAG_STOPONWARNING | TJFLAG_LIMITSCANS;
  if (tjDecompress2(tj.get(), bytes.data(), bytes.size(), decoded.data, width,
                    static_cast<int>(decoded.step[0]), height, pixel_format,
                    flags) != 0) {
    if (tjGetErrorCode(tj.get()) == TJERR_WARNING) {
      ThrowInputError(path, "corrupt JPEG data (libjpeg warning: ",
                      OneLine(tjGetErrorStr2(tj.get())), ")");
    }
    ThrowInputError(path, "cannot decode JPEG (libjpeg: ",
                    OneLine(tjGetErrorStr2(tj.get())), ")");
  }
  cv::Mat image;
  if (!cmyk) {
    image = decoded;
  } else if (gray_out) {
    CmykToGray(decoded, &image);
  } else {
    CmykToColor(decoded, rgb, &image);
  }
  if (request.mode != Mode::kUnchanged)
    ApplyOrientation(JpegOrientation(scan), &image);
  return image;
}

// ---- PNG ----

struct PngScan {
  bool complete = false;  // the chunk sequence reaches IEND
  uint32_t width = 0, height = 0;
  // The first eXIf chunk whose data starts with a TIFF byte order ("II" or
  // "MM"), as libpng keeps it.
  const uint8_t* exif = nullptr;
  size_t exif_size = 0;
};

// Walks the PNG chunk structure up to IEND (lengths and types only; libspng
// checks the CRCs while decoding).
PngScan ScanPng(const std::vector<uint8_t>& b) {
  PngScan scan;
  if (b.size() >= 24 && std::memcmp(&b[12], "IHDR", 4) == 0) {
    scan.width = Be32(&b[16]);
    scan.height = Be32(&b[20]);
  }
  size_t i = 8;
  while (i + 8 <= b.size()) {
    const uint64_t length = Be32(&b[i]);
    if (i + 12 + length > b.size()) return scan;
    const uint8_t* type = &b[i + 4];
    if (std::memcmp(type, "IEND", 4) == 0) {
      scan.complete = true;
      return scan;
    }
    if (std::memcmp(type, "eXIf", 4) == 0 && scan.exif == nullptr &&
        length >= 2 && b[i + 8] == b[i + 9] &&
        (b[i + 8] == 'I' || b[i + 8] == 'M')) {
      scan.exif = &b[i + 8];
      scan.exif_size = length;
    }
    i += 12 + length;
  }
  return scan;
}

struct SpngDeleter {
  void operator()(spng_ctx* ctx) const { spng_ctx_free(ctx); }
};
using SpngContext = std::unique_ptr<spng_ctx, SpngDeleter>;

[[noreturn]] void ThrowSpng(const std::string& path, int error) {
  ThrowInputError(
      path, "cannot decode PNG (libspng: ", OneLine(spng_strerror(error)), ")");
}

// libpng's rgb-to-gray as OpenCV sets it up (png_set_rgb_to_gray(png, 1,
// 0.299, 0.587): coefficients 9797, 19234 and 3737 in 1/32768), including the
// linear-light path libpng takes for 8-bit data when the file declares a
// significant gamma (gAMA, or sRGB = 0.45455).
class RgbToGray {
 public:
  // file_gamma: libpng's fixed point (100000 = 1.0), 0 when the file has none.
  explicit RgbToGray(uint32_t file_gamma) {
    auto significant = [](uint32_t g) { return g < 95000 || g > 105000; };
    auto reciprocal = [](double g) {
      return static_cast<uint32_t>(std::floor(1e10 / g + 0.5));
    };
    if (file_gamma == 0 || !significant(file_gamma)) return;
    const uint32_t screen = reciprocal(file_gamma);
    Build8(reciprocal(file_gamma), significant, &to_linear_);
    Build8(reciprocal(screen), significant, &from_linear_);
    Build8(static_cast<uint32_t>(std::floor(
               1e15 / file_gamma / static_cast<double>(screen) + 0.5)),
           significant, &same_);
    gamma_ = true;
  }

  uint8_t Gray8(int r, int g, int b) const {
    if (r == g && g == b) return gamma_ ? same_[r] : static_cast<uint8_t>(r);
    if (!gamma_) return static_cast<uint8_t>((kR * r + kG * g + kB * b) >> 15);
    const uint32_t y = (kR * to_linear_[r] + kG * to_linear_[g] +
                        kB * to_linear_[b] + 16384) >>
                       15;
    return from_linear_[y];
  }
  // 16-bit samples: libpng rounds, then OpenCV strips to the high byte. (The
  // gamma path of 16-bit data is not reproduced.)
  uint8_t Gray16(int r, int g, int b) const {
    return static_cast<uint8_t>(((kR * r + kG * g + kB * b + 16384) >> 15) >>
                                8);
  }

 private:
  static constexpr uint32_t kR = 9797, kG = 19234, kB = 32768 - kR - kG;

  template <typename Significant>
  static void Build8(uint32_t gamma,
                     Significant significant,
                     uint8_t (*table)[256]) {
    for (int i = 0; i < 256; ++i) {
      (*table)[i] = static_cast<uint8_t>(i);
      if (significant(gamma) && i > 0 && i < 255) {
        (*table)[i] = static_cast<uint8_t>(
            std::floor(255 * std::pow(i / 255.0, gamma * 1e-5) + 0.5));
      }
    }
  }

  bool gamma_ = false;
  uint8_t to_linear_[256], from_linear_[256], same_[256];
};

// Swaps channels 0 and 2 (RGB <-> BGR, RGBA <-> BGRA) in place.
void SwapRedBlue(cv::Mat* image) {
  const int cn = image->channels();
  if (cn < 3) return;
  for (int y = 0; y < image->rows; ++y) {
    if (image->depth() == CV_16U) {
      uint16_t* p = image->ptr<uint16_t>(y);
      for (int x = 0; x < image->cols; ++x, p += cn) std::swap(p[0], p[2]);
    } else {
      uint8_t* p = image->ptr<uint8_t>(y);
      for (int x = 0; x < image->cols; ++x, p += cn) std::swap(p[0], p[2]);
    }
  }
}

cv::Mat DecodePng(const std::string& path,
                  const std::vector<uint8_t>& bytes,
                  const Request& request) {
  const PngScan scan = ScanPng(bytes);
  if (!scan.complete)
    ThrowInputError(path, "truncated or corrupt PNG (no IEND chunk)");
  if (scan.width != 0 && scan.height != 0)
    CheckLimits(path, scan.width, scan.height);

  SpngContext ctx(spng_ctx_new(0));
  if (!ctx) ThrowInputError(path, "cannot start libspng (out of memory)");
  // CRC errors in any chunk are errors (libpng and libspng discard ancillary
  // chunks with a bad CRC by default).
  spng_set_crc_action(ctx.get(), SPNG_CRC_ERROR, SPNG_CRC_ERROR);
  spng_set_image_limits(ctx.get(), ImageReadLimits::kMaxSide,
                        ImageReadLimits::kMaxSide);
  spng_set_chunk_limits(ctx.get(), kMaxPngChunkBytes, kMaxPngChunkBytes);
  int err = spng_set_png_buffer(ctx.get(), bytes.data(), bytes.size());
  if (err != 0) ThrowSpng(path, err);
  spng_ihdr ihdr{};
  if ((err = spng_get_ihdr(ctx.get(), &ihdr)) != 0) ThrowSpng(path, err);
  CheckLimits(path, ihdr.width, ihdr.height);
  spng_trns trns{};
  err = spng_get_trns(ctx.get(), &trns);  // reads every chunk before IDAT
  if (err != 0 && err != SPNG_ECHUNKAVAIL) ThrowSpng(path, err);
  const bool has_trns = err == 0;

  const int w = static_cast<int>(ihdr.width);
  const int h = static_cast<int>(ihdr.height);
  const int ct = ihdr.color_type;
  const bool deep = ihdr.bit_depth == 16;
  const bool gray_file =
      ct == SPNG_COLOR_TYPE_GRAYSCALE || ct == SPNG_COLOR_TYPE_GRAYSCALE_ALPHA;
  const bool alpha_file = ct == SPNG_COLOR_TYPE_GRAYSCALE_ALPHA ||
                          ct == SPNG_COLOR_TYPE_TRUECOLOR_ALPHA;
  const int file_channels = ct == SPNG_COLOR_TYPE_GRAYSCALE         ? 1
                            : ct == SPNG_COLOR_TYPE_GRAYSCALE_ALPHA ? 2
                            : ct == SPNG_COLOR_TYPE_TRUECOLOR       ? 3
                                                                    : 4;

  // The decode format and the buffer it fills.
  int fmt = SPNG_FMT_RGB8;
  int decode_flags = 0;
  int buffer_type = CV_8UC3;
  switch (request.mode) {
    case Mode::kColor:  // alpha dropped, 16 bits -> high byte, gray replicated
      break;
    case Mode::kGray:
      if (ct == SPNG_COLOR_TYPE_GRAYSCALE && !deep) {
        fmt = SPNG_FMT_G8;
        buffer_type = CV_8UC1;
      } else if (gray_file || (deep && ct != SPNG_COLOR_TYPE_INDEXED)) {
        fmt = SPNG_FMT_PNG;  // raw samples, host byte order
        buffer_type = CV_MAKETYPE(deep ? CV_16U : CV_8U, file_channels);
      }  // else 8-bit colour or palette: RGB8, then libpng's rgb-to-gray
      break;
    case Mode::kUnchanged:
      // OpenCV: gray stays 1 channel (tRNS ignored), gray+alpha and RGBA
      // become 4 channels, RGB and palette 3 (4 with tRNS, as alpha).
      if (ct == SPNG_COLOR_TYPE_GRAYSCALE) {
        fmt = deep ? SPNG_FMT_PNG : SPNG_FMT_G8;
        buffer_type = deep ? CV_16UC1 : CV_8UC1;
      } else if (alpha_file || has_trns) {
        fmt = deep ? SPNG_FMT_RGBA16 : SPNG_FMT_RGBA8;
        decode_flags = SPNG_DECODE_TRNS;
        buffer_type = deep ? CV_16UC4 : CV_8UC4;
      } else if (deep) {
        fmt = SPNG_FMT_PNG;
        buffer_type = CV_16UC3;
      }
      break;
  }
  cv::Mat buffer(h, w, buffer_type);
  size_t size = 0;
  if ((err = spng_decoded_image_size(ctx.get(), fmt, &size)) != 0)
    ThrowSpng(path, err);
  if (size != buffer.total() * buffer.elemSize())
    ThrowInputError(path, "cannot decode PNG (unexpected decoded size)");
  if ((err = spng_decode_image(ctx.get(), buffer.data, size, fmt,
                               decode_flags)) != 0) {
    ThrowSpng(path, err);
  }
  // The chunks after the image data, to IEND (CRCs checked).
  if ((err = spng_decode_chunks(ctx.get())) != 0) ThrowSpng(path, err);

  cv::Mat image;
  if (request.mode == Mode::kGray && buffer.channels() == 1 &&
      buffer.depth() == CV_8U) {
    image = buffer;
  } else if (request.mode == Mode::kGray) {
    uint32_t gamma = 0;
    uint8_t intent = 0;
    if (spng_get_srgb(ctx.get(), &intent) == 0) {
      gamma = 45455;
    } else if (spng_get_gama_int(ctx.get(), &gamma) != 0) {
      gamma = 0;
    }
    const RgbToGray to_gray(gamma);
    image.create(h, w, CV_8UC1);
    const int cn = buffer.channels();
    for (int y = 0; y < h; ++y) {
      uint8_t* d = image.ptr<uint8_t>(y);
      if (buffer.depth() == CV_16U) {
        const uint16_t* s = buffer.ptr<uint16_t>(y);
        for (int x = 0; x < w; ++x, s += cn) {
          d[x] = cn < 3 ? static_cast<uint8_t>(s[0] >> 8)
                        : to_gray.Gray16(s[0], s[1], s[2]);
        }
      } else {
        const uint8_t* s = buffer.ptr<uint8_t>(y);
        for (int x = 0; x < w; ++x, s += cn)
          d[x] = cn < 3 ? s[0] : to_gray.Gray8(s[0], s[1], s[2]);
      }
    }
  } else {
    image = buffer;
    if (!(request.mode == Mode::kColor && request.rgb)) SwapRedBlue(&image);
  }
  if (request.mode != Mode::kUnchanged)
    ApplyOrientation(ExifOrientation(scan.exif, scan.exif_size), &image);
  return image;
}

// ---- Reading ----

// Throws InputError naming `path` unless `bytes` start as a JPEG or a PNG.
void CheckImageBytes(const std::string& path,
                     const std::vector<uint8_t>& bytes) {
  if (bytes.empty()) ThrowInputError(path, "empty file (expected an image)");
  if (!IsJpeg(bytes) && !IsPng(bytes)) {
    ThrowInputError(path,
                    "not a readable image (unknown format or corrupt data)");
  }
}

// Reads an image file; throws InputError naming it when unreadable.
std::mutex& ResolverMutex() {
  static std::mutex mutex;
  return mutex;
}
std::map<std::string, ImageBytesResolver>& Resolvers() {
  static std::map<std::string, ImageBytesResolver> resolvers;
  return resolvers;
}

// True and *bytes if a registered resolver owns `path`.
bool ResolveImageBytes(const std::string& path, std::vector<uint8_t>* bytes) {
  std::vector<ImageBytesResolver> resolvers;
  {
    std::lock_guard<std::mutex> lock(ResolverMutex());
    if (Resolvers().empty()) return false;
    for (const auto& [name, r] : Resolvers()) resolvers.push_back(r);
  }
  for (const ImageBytesResolver& r : resolvers)
    if (r(path, bytes)) return true;
  return false;
}

std::vector<uint8_t> ReadImageBytes(const std::string& path) {
  std::vector<uint8_t> bytes;
  if (ResolveImageBytes(path, &bytes)) {
    CheckImageBytes(path, bytes);
    return bytes;
  }
  bytes = ReadFileBytes(path, kMaxImageFileBytes);
  CheckImageBytes(path, bytes);
  return bytes;
}

cv::Mat Decode(const std::string& path, const Request& request) {
  const std::vector<uint8_t> bytes = ReadImageBytes(path);
  return IsJpeg(bytes) ? DecodeJpeg(path, bytes, request)
                       : DecodePng(path, bytes, request);
}

// ---- Writing ----

struct SpngBuffer {
  void operator()(void* p) const { std::free(p); }
};

std::vector<uint8_t> EncodePng(const std::string& path, const cv::Mat& image) {
  const cv::Mat data = image.isContinuous() ? image : image.clone();
  SpngContext ctx(spng_ctx_new(SPNG_CTX_ENCODER));
  if (!ctx) ThrowInputError(path, "cannot start libspng (out of memory)");
  auto check = [&](int err) {
    if (err != 0) {
      ThrowInputError(path, "cannot encode PNG (libspng: ",
                      OneLine(spng_strerror(err)), ")");
    }
  };
  check(spng_set_option(ctx.get(), SPNG_ENCODE_TO_BUFFER, 1));
  // zlib level 3 with the default strategy and libspng's adaptive filter
  // choice: deterministic for a given zlib.
  check(spng_set_option(ctx.get(), SPNG_IMG_COMPRESSION_LEVEL, 3));
  spng_ihdr ihdr{};
  ihdr.width = static_cast<uint32_t>(data.cols);
  ihdr.height = static_cast<uint32_t>(data.rows);
  ihdr.bit_depth = data.depth() == CV_16U ? 16 : 8;
  ihdr.color_type = data.channels() == 1   ? SPNG_COLOR_TYPE_GRAYSCALE
                    : data.channels() == 3 ? SPNG_COLOR_TYPE_TRUECOLOR
                                           : SPNG_COLOR_TYPE_TRUECOLOR_ALPHA;
  check(spng_set_ihdr(ctx.get(), &ihdr));
  check(spng_encode_image(ctx.get(), data.data, data.total() * data.elemSize(),
                          SPNG_FMT_PNG, SPNG_ENCODE_FINALIZE));
  size_t size = 0;
  int err = 0;
  std::unique_ptr<void, SpngBuffer> png(
      spng_get_png_buffer(ctx.get(), &size, &err));
  check(err);
  if (!png) check(SPNG_EINTERNAL);
  const uint8_t* p = static_cast<const uint8_t*>(png.get());
  return std::vector<uint8_t>(p, p + size);
}

std::vector<uint8_t> EncodeJpeg(const std::string& path,
                                const cv::Mat& image,
                                int quality) {
  if (image.empty()) ThrowInputError(path, "cannot encode an empty image");
  const int cn = image.channels();
  if (image.depth() != CV_8U || (cn != 1 && cn != 3 && cn != 4)) {
    ThrowInputError(path, "JPEG needs an 8-bit image (gray, RGB or RGBA; ",
                    "got OpenCV type ", image.type(), ")");
  }
  if (quality < 1 || quality > 100)
    ThrowInputError(path, "JPEG quality ", quality, " is not in [1, 100]");
  TjHandle tj = NewTjHandle(path, /*decompress=*/false);
  const int pixel_format = cn == 1 ? TJPF_GRAY : cn == 3 ? TJPF_RGB : TJPF_RGBA;
  unsigned char* jpeg = nullptr;
  unsigned long size = 0;  // NOLINT(runtime/int): TurboJPEG's type
  // OpenCV's settings: 4:2:0, standard Huffman tables and the accurate
  // integer DCT (TurboJPEG would take the fast one below quality 96), so that
  // the files are byte-identical to cv::imencode's.
  const int rc = tjCompress2(
      tj.get(), image.data, image.cols, static_cast<int>(image.step[0]),
      image.rows, pixel_format, &jpeg, &size,
      cn == 1 ? TJSAMP_GRAY : TJSAMP_420, quality, TJFLAG_ACCURATEDCT);
  std::unique_ptr<unsigned char, void (*)(unsigned char*)> owned(jpeg, tjFree);
  if (rc != 0) {
    ThrowInputError(path, "cannot encode JPEG (libjpeg: ",
                    OneLine(tjGetErrorStr2(tj.get())), ")");
  }
  return std::vector<uint8_t>(jpeg, jpeg + size);
}

}  // namespace

void RegisterImageBytesResolver(const std::string& name,
                                ImageBytesResolver resolver) {
  std::lock_guard<std::mutex> lock(ResolverMutex());
  Resolvers().emplace(name, std::move(resolver));
}

std::vector<uint8_t> EncodePngImage(const cv::Mat& image) {
  return EncodePng("in-memory PNG", image);
}

cv::Mat ReadImageRgb(const std::string& path) {
  return Decode(path, {Mode::kColor, /*rgb=*/true, JpegScale{}});
}

cv::Mat ReadImageGray(const std::string& path) {
  return Decode(path, {Mode::kGray, /*rgb=*/false, JpegScale{}});
}

cv::Mat ReadImageUnchanged(const std::string& path) {
  return Decode(path, {Mode::kUnchanged, /*rgb=*/false, JpegScale{}});
}

cv::Mat ReadImageRgbScaled(const std::string& path,
                           int min_width,
                           int min_height) {
  const std::vector<uint8_t> bytes = ReadImageBytes(path);
  Request request{Mode::kColor, /*rgb=*/true, JpegScale{}};
  if (IsPng(bytes)) return DecodePng(path, bytes, request);
  const JpegScan scan = ScanJpeg(bytes);
  if (!scan.complete)
    ThrowInputError(path, "truncated or corrupt JPEG (no end-of-image marker)");
  JpegHeader header;
  {
    TjHandle tj = NewTjHandle(path, /*decompress=*/true);
    header = ReadJpegHeader(path, tj.get(), bytes);
  }
  // Wanted size in the file's (unrotated) frame.
  if (SwapsSides(JpegOrientation(scan))) std::swap(min_width, min_height);
  for (int denom : {8, 4, 2}) {
    const tjscalingfactor f{1, denom};
    if (TJSCALED(header.width, f) >= min_width &&
        TJSCALED(header.height, f) >= min_height &&
        TjPicksScale(header.width, header.height, f)) {
      request.scale = {1, denom};
      break;
    }
  }
  return DecodeJpeg(path, bytes, request);
}

std::vector<JpegScale> JpegDecodeScales(int width, int height) {
  std::vector<JpegScale> scales;
  int count = 0;
  const tjscalingfactor* factors = tjGetScalingFactors(&count);
  // The list runs from the largest factor (2/1) to the smallest (1/8).
  for (int i = factors == nullptr ? -1 : count - 1; i >= 0; --i) {
    const tjscalingfactor& f = factors[i];
    if (f.num > f.denom) continue;
    if (width > 0 && height > 0 && !TjPicksScale(width, height, f)) continue;
    scales.push_back({f.num, f.denom});
  }
  if (scales.empty() || scales.back().num != scales.back().denom)
    scales.push_back({1, 1});
  return scales;
}

cv::Mat ReadImageRgbScaled(const std::string& path, JpegScale scale) {
  return DecodeImageRgb(ReadImageFile(path), scale);
}

ImageFile ReadImageFile(const std::string& path) {
  return ImageFile{path, ReadImageBytes(path)};
}

cv::Mat DecodeImageRgb(const ImageFile& file, JpegScale scale) {
  const std::string& path = file.path;
  const std::vector<uint8_t>& bytes = file.bytes;
  CheckImageBytes(path, bytes);
  Request request{Mode::kColor, /*rgb=*/true, JpegScale{}};
  if (IsPng(bytes)) return DecodePng(path, bytes, request);
  if (scale.num == 1 && scale.denom == 1)  // ReadImageRgb
    return DecodeJpeg(path, bytes, request);
  if (!ScanJpeg(bytes).complete)
    ThrowInputError(path, "truncated or corrupt JPEG (no end-of-image marker)");
  JpegHeader header;
  {
    TjHandle tj = NewTjHandle(path, /*decompress=*/true);
    header = ReadJpegHeader(path, tj.get(), bytes);
  }
  bool supported = false;
  if (scale.num > 0 && scale.denom > 0) {
    for (const JpegScale& s : JpegDecodeScales(header.width, header.height)) {
      supported =
          supported || SameScale({s.num, s.denom}, {scale.num, scale.denom});
    }
  }
  if (!supported) {
    ThrowInputError(path, "cannot decode a ", header.width, "x", header.height,
                    " JPEG at scale ", scale.num, "/", scale.denom,
                    " (not one of libjpeg-turbo's scales for that size)");
  }
  request.scale = scale;
  return DecodeJpeg(path, bytes, request);
}

void WriteImageRgb(const std::string& path, const cv::Mat& rgb) {
  if (rgb.empty()) ThrowInputError(path, "cannot write an empty image");
  const int type = rgb.type();
  if (type != CV_8UC1 && type != CV_16UC1 && type != CV_8UC3 &&
      type != CV_16UC3 && type != CV_8UC4) {
    ThrowInputError(path, "cannot write image of OpenCV type ", type,
                    " (expected 8-bit RGB, RGBA or gray, or 16-bit RGB or "
                    "gray)");
  }
  const std::string name = LowerFileName(path);
  const size_t dot = name.rfind('.');
  if (dot == std::string::npos)
    ThrowInputError(path, "no file extension (expected .png or .jpg)");
  const std::string ext = name.substr(dot);
  std::vector<uint8_t> encoded;
  if (ext == ".png") {
    encoded = EncodePng(path, rgb);
  } else if (ext == ".jpg" || ext == ".jpeg") {
    encoded = EncodeJpeg(path, rgb, 95);
  } else {
    ThrowInputError(path, "cannot encode image as ", ext,
                    " (expected .png, .jpg or .jpeg)");
  }
  WriteFileAtomic(path, encoded.data(), encoded.size());
}

std::vector<uint8_t> EncodeJpegRgb(const cv::Mat& rgb,
                                   int quality,
                                   const std::string& what) {
  return EncodeJpeg(what, rgb, quality);
}

void WriteJpeg(const std::string& path, const cv::Mat& rgb, int quality) {
  const std::vector<uint8_t> encoded = EncodeJpeg(path, rgb, quality);
  WriteFileAtomic(path, encoded.data(), encoded.size());
}

ImageHeader ReadImageHeader(const std::string& path) {
  return ReadImageHeader(ReadImageFile(path));
}

ImageHeader ReadImageHeader(const ImageFile& file) {
  const std::string& path = file.path;
  const std::vector<uint8_t>& bytes = file.bytes;
  CheckImageBytes(path, bytes);
  int width = 0, height = 0, orientation = 1;
  ImageHeader header;
  header.jpeg = !IsPng(bytes);
  if (!header.jpeg) {
    const PngScan scan = ScanPng(bytes);
    if (!scan.complete)
      ThrowInputError(path, "truncated or corrupt PNG (no IEND chunk)");
    if (scan.width == 0 || scan.height == 0)
      ThrowInputError(path, "not a readable PNG (no IHDR chunk)");
    CheckLimits(path, scan.width, scan.height);
    width = static_cast<int>(scan.width);
    height = static_cast<int>(scan.height);
    orientation = ExifOrientation(scan.exif, scan.exif_size);
  } else {
    const JpegScan scan = ScanJpeg(bytes);
    if (!scan.complete)
      ThrowInputError(path,
                      "truncated or corrupt JPEG (no end-of-image marker)");
    TjHandle tj = NewTjHandle(path, /*decompress=*/true);
    const JpegHeader header = ReadJpegHeader(path, tj.get(), bytes);
    width = header.width;
    height = header.height;
    orientation = JpegOrientation(scan);
  }
  // ApplyOrientation leaves the image as stored for any other value.
  header.orientation = orientation >= 1 && orientation <= 8 ? orientation : 1;
  header.size = SwapsSides(header.orientation) ? cv::Size(height, width)
                                               : cv::Size(width, height);
  return header;
}

cv::Size ReadImageSize(const std::string& path) {
  return ReadImageHeader(path).size;
}

}  // namespace geodrive
