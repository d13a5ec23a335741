#include "geometry/image_io.h"

#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "geometry/util/files.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

constexpr uint64_t kMaxImageFileBytes = 1ull << 31;  // 2 GiB

bool IsJpeg(const std::vector<uint8_t>& b) {
  return b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF;
}
bool IsPng(const std::vector<uint8_t>& b) {
  static const uint8_t kSig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  return b.size() >= 8 && std::memcmp(b.data(), kSig, 8) == 0;
}

struct JpegScan {
  bool complete = false;  // reached the EOI marker
  bool has_exif = false;  // an APP1 "Exif" segment (orientation may rotate the
                          // decoded image)
  int width = 0, height = 0;
};

// Walks the JPEG marker structure (segments, then entropy-coded scans) up to
// EOI. libjpeg only warns on a truncated file and returns a partly grey image;
// this makes truncation an error.
JpegScan ScanJpeg(const std::vector<uint8_t>& b) {
  JpegScan scan;
  size_t i = 2;  // after SOI
  const size_t n = b.size();
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
    if (is_sof && length >= 7) {
      scan.height = (b[i + 3] << 8) | b[i + 4];
      scan.width = (b[i + 5] << 8) | b[i + 6];
    }
    if (marker == 0xE1 && length >= 8 &&
        std::memcmp(&b[i + 2], "Exif", 4) == 0) {
      scan.has_exif = true;
    }
    i += length;
    if (marker == 0xDA) {
      // Entropy-coded data: ends at the first marker that is not a stuffed
      // 0xFF00 or RSTn.
      while (i + 1 < n) {
        if (b[i] == 0xFF && b[i + 1] != 0x00 &&
            !(b[i + 1] >= 0xD0 && b[i + 1] <= 0xD7))
          break;
        ++i;
      }
    }
  }
  return scan;
}

// True if the PNG chunk sequence is complete up to IEND (libpng prints to
// stderr on a truncated file; checking first keeps errors to one line).
bool PngComplete(const std::vector<uint8_t>& b) {
  size_t i = 8;
  while (i + 8 <= b.size()) {
    const uint64_t length = (uint64_t{b[i]} << 24) |
                            (uint64_t{b[i + 1]} << 16) |
                            (uint64_t{b[i + 2]} << 8) | uint64_t{b[i + 3]};
    const bool iend = std::memcmp(&b[i + 4], "IEND", 4) == 0;
    if (length > b.size() || i + 12 + length > b.size()) return false;
    if (iend) return true;
    i += 12 + length;
  }
  return false;
}

// Reads and sanity-checks an image file; throws InputError naming it when
// unreadable.
std::vector<uint8_t> ReadImageFile(const std::string& path) {
  std::vector<uint8_t> bytes =
      ReadFileBytes(path, kMaxImageFileBytes);
  if (bytes.empty()) ThrowInputError(path, "empty file (expected an image)");
  if (IsJpeg(bytes) && !ScanJpeg(bytes).complete) {
    ThrowInputError(path, "truncated or corrupt JPEG (no end-of-image marker)");
  }
  if (IsPng(bytes) && !PngComplete(bytes)) {
    ThrowInputError(path, "truncated or corrupt PNG (no IEND chunk)");
  }
  return bytes;
}

cv::Mat Decode(const std::string& path, int flags) {
  const std::vector<uint8_t> bytes = ReadImageFile(path);
  cv::Mat image;
  try {
    image = cv::imdecode(bytes, flags);
  } catch (const cv::Exception& e) {
    ThrowInputError(path, "cannot decode image (", e.err, ")");
  }
  if (image.empty()) {
    ThrowInputError(
        path, IsPng(bytes) || IsJpeg(bytes)
                  ? "cannot decode image (truncated or corrupt data)"
                  : "not a readable image (unknown format or corrupt data)");
  }
  return image;
}

}  // namespace

cv::Mat ReadImageRgb(const std::string& path) {
  cv::Mat bgr = Decode(path, cv::IMREAD_COLOR);
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

cv::Mat ReadImageGray(const std::string& path) {
  return Decode(path, cv::IMREAD_GRAYSCALE);
}

cv::Mat ReadImageUnchanged(const std::string& path) {
  return Decode(path, cv::IMREAD_UNCHANGED);
}

void WriteImageRgb(const std::string& path, const cv::Mat& rgb) {
  if (rgb.empty()) ThrowInputError(path, "cannot write an empty image");
  cv::Mat out;
  switch (rgb.type()) {
    case CV_8UC1:
    case CV_16UC1:
      out = rgb;
      break;
    case CV_8UC3:
      cv::cvtColor(rgb, out, cv::COLOR_RGB2BGR);
      break;
    case CV_8UC4:
      cv::cvtColor(rgb, out, cv::COLOR_RGBA2BGRA);
      break;
    default:
      ThrowInputError(path, "cannot write image of OpenCV type ", rgb.type(),
                      " (expected 8-bit RGB, RGBA or gray, or 16-bit gray)");
  }
  const std::string name = LowerFileName(path);
  const size_t dot = name.rfind('.');
  if (dot == std::string::npos)
    ThrowInputError(path, "no file extension (expected .png or .jpg)");
  const std::string ext = name.substr(dot);
  std::vector<int> params;
  if (ext == ".png") {
    params = {cv::IMWRITE_PNG_COMPRESSION, 3};
  } else if (ext == ".jpg" || ext == ".jpeg") {
    params = {cv::IMWRITE_JPEG_QUALITY, 95};
    if (out.depth() != CV_8U)
      ThrowInputError(path, "JPEG needs an 8-bit image");
  }
  std::vector<uint8_t> encoded;
  bool ok = false;
  try {
    ok = cv::imencode(ext, out, encoded, params);
  } catch (const cv::Exception& e) {
    ThrowInputError(path, "cannot encode image as ", ext, " (", e.err, ")");
  }
  if (!ok) ThrowInputError(path, "cannot encode image as ", ext);
  WriteFileAtomic(path, encoded.data(), encoded.size());
}

cv::Size ReadImageSize(const std::string& path) {
  std::vector<uint8_t> head = ReadFileBytes(path, kMaxImageFileBytes);
  if (IsPng(head) && head.size() >= 24 &&
      std::memcmp(&head[12], "IHDR", 4) == 0) {
    auto be32 = [&](size_t o) {
      return static_cast<int>(
          (uint32_t{head[o]} << 24) | (uint32_t{head[o + 1]} << 16) |
          (uint32_t{head[o + 2]} << 8) | uint32_t{head[o + 3]});
    };
    return cv::Size(be32(16), be32(20));
  }
  if (IsJpeg(head)) {
    const JpegScan scan = ScanJpeg(head);
    if (!scan.complete)
      ThrowInputError(path,
                      "truncated or corrupt JPEG (no end-of-image marker)");
    if (!scan.has_exif && scan.width > 0 && scan.height > 0) {
      return cv::Size(scan.width, scan.height);
    }
  }
  // Other formats, or EXIF orientation that may swap the sides: decode
  // (IMREAD_COLOR applies the orientation, as ReadImageRgb does).
  const cv::Mat image =
      Decode(path, IsJpeg(head) ? cv::IMREAD_COLOR : cv::IMREAD_UNCHANGED);
  return image.size();
}

}  // namespace geodrive
