#pragma once
// PNG and JPEG reading and writing through the codec libraries themselves:
// libjpeg-turbo's TurboJPEG API and libspng (no OpenCV imgcodecs). Pixels are
// identical to what cv::imdecode returns for the same file and flags (OpenCV
// 4.6, same libjpeg-turbo), EXIF orientation included. Hardened: the header is
// checked against ImageReadLimits before any pixel memory is allocated; a JPEG
// that libjpeg decodes only "with warnings" (corrupt or missing scan data), a
// truncated file and a PNG chunk with a bad CRC are errors. Every failure is
// one InputError naming the file; the libraries print nothing. Writes are
// atomic (temporary file + rename) and deterministic.

#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace geodrive {

// The largest image the readers accept, checked on the header (JPEG SOF, PNG
// IHDR) before any pixel memory is allocated. A 16384 x 16384 RGB image
// decodes to 768 MiB; 2^28 pixels bound a 16-bit RGBA decode to 2 GiB.
struct ImageReadLimits {
  static constexpr int kMaxSide = 16384;                   // pixels per side
  static constexpr int64_t kMaxPixels = int64_t{1} << 28;  // width * height
};

// Reads an 8-bit image as RGB (3 channels, CV_8UC3) -- note: RGB, not OpenCV's
// BGR. Alpha is dropped, 16-bit samples keep their high byte, gray is
// replicated, EXIF orientation is applied (as cv::IMREAD_COLOR).
cv::Mat ReadImageRgb(const std::string& path);
// Reads a single-channel 8-bit image (e.g. a mask) as CV_8UC1, EXIF
// orientation applied (as cv::IMREAD_GRAYSCALE).
cv::Mat ReadImageGray(const std::string& path);
// Reads an image unchanged (8- or 16-bit; 1, 3 or 4 channels), BGR/BGRA order
// as OpenCV stores it, EXIF orientation not applied (as cv::IMREAD_UNCHANGED).
cv::Mat ReadImageUnchanged(const std::string& path);
// A JPEG decoding scale num/denom. libjpeg scales in the DCT domain: the
// inverse DCT of each 8x8 block yields 8 * num / denom samples per side, which
// skips most of the IDCT, colour-conversion and upsampling work of a full
// decode (the entropy decoding is not reduced).
struct JpegScale {
  int num = 1;
  int denom = 1;
};

// The scales at or below 1/1 at which ReadImageRgbScaled decodes a JPEG of
// width x height pixels, smallest first: the scaling factors this
// libjpeg-turbo lists (tjGetScalingFactors; 1/8, 1/4, 3/8, 1/2, 5/8, 3/4, 7/8
// and 1/1 in libjpeg-turbo 2.1), less any that TurboJPEG would not pick for its
// own output size (a larger factor with the same rounded size wins; only tiny
// images). Symmetric in width and height.
std::vector<JpegScale> JpegDecodeScales(int width, int height);

// Reads as ReadImageRgb, but decodes a JPEG at the smallest of the scales 1/8,
// 1/4, 1/2 and 1 (libjpeg's DCT scaling, much faster than decoding then
// resizing) whose output is still at least min_width x min_height (after EXIF
// orientation); same pixels as cv::IMREAD_REDUCED_COLOR_{2,4,8}. PNGs are read
// at full size.
cv::Mat ReadImageRgbScaled(const std::string& path,
                           int min_width,
                           int min_height);
// Reads as ReadImageRgb, but decodes a JPEG at `scale`, one of
// JpegDecodeScales() for its size (InputError naming the file otherwise). A W
// x H JPEG comes out ceil(W * num / denom) x ceil(H * num / denom), and output
// pixel j covers the source pixels [j * denom / num, (j + 1) * denom / num)
// along each axis: where W * num / denom is not whole, the last column reaches
// past the source's edge (libjpeg repeats the edge there), so a caller that
// maps pixel centres must use the unrounded size, not the decoded one. EXIF
// orientation is applied after the decode: an orientation that reverses an
// axis puts that partial pixel first (ReadImageHeader gives the orientation).
// PNGs are read at full size.
cv::Mat ReadImageRgbScaled(const std::string& path, JpegScale scale);

// Writes an RGB CV_8UC3 image (also RGBA CV_8UC4, gray CV_8UC1 and, PNG only,
// 16-bit gray CV_16UC1 and 16-bit RGB CV_16UC3); the format follows the
// extension (.png, .jpg/.jpeg).
// PNG: libspng, compression level 3, deterministic, exact round trip. JPEG:
// TurboJPEG, quality 95, 4:2:0 (gray stays gray, alpha is dropped).
void WriteImageRgb(const std::string& path, const cv::Mat& rgb);

// JPEG encoding at a chosen quality (1..100) through TurboJPEG with OpenCV's
// cv::imencode(".jpg") settings: 4:2:0 chroma subsampling (gray stays gray),
// the accurate integer DCT, standard Huffman tables, a JFIF header, baseline.
// `rgb` is RGB CV_8UC3, RGBA CV_8UC4 (alpha dropped) or gray CV_8UC1. The
// bytes equal cv::imencode's with IMWRITE_JPEG_QUALITY = quality on the
// channel-swapped image (same libjpeg-turbo), and are deterministic. Throws
// InputError naming `what` (a file name or a description) on a bad image or
// quality. WriteImageRgb's .jpg is EncodeJpegRgb(rgb, 95).
std::vector<uint8_t> EncodeJpegRgb(const cv::Mat& rgb,
                                   int quality,
                                   const std::string& what = "JPEG encoder");
// EncodeJpegRgb written atomically (temporary file + rename) to `path`.
void WriteJpeg(const std::string& path, const cv::Mat& rgb, int quality);

// What the header of an image file says (JPEG SOF and EXIF orientation, PNG
// IHDR and eXIf): nothing is decoded. Truncated files and images over
// ImageReadLimits are errors, as for the readers.
struct ImageHeader {
  // The size ReadImageRgb returns (EXIF orientation applied).
  cv::Size size;
  // The EXIF orientation ReadImageRgb applies, 1..8 (1: as stored; absent and
  // invalid values read as 1).
  int orientation = 1;
  // A JPEG (else a PNG).
  bool jpeg = false;
};
ImageHeader ReadImageHeader(const std::string& path);
// ReadImageHeader(path).size.
cv::Size ReadImageSize(const std::string& path);

// An image file read into memory once, for a header check and a decode that
// would otherwise each read (and scan) the file.
struct ImageFile {
  std::string path;            // named in errors
  std::vector<uint8_t> bytes;  // the whole file
};
// Reads `path` (InputError naming it when unreadable, empty or neither a JPEG
// nor a PNG).
ImageFile ReadImageFile(const std::string& path);
// ReadImageHeader of a file already read.
ImageHeader ReadImageHeader(const ImageFile& file);
// ReadImageRgbScaled(path, scale) of a file already read: the same pixels and
// errors; scale 1/1 is ReadImageRgb(path).
cv::Mat DecodeImageRgb(const ImageFile& file, JpegScale scale = {});

// Images stored inside container files (a camera image of a Waymo TFRecord
// frame, "<segment>.tfrecord#<record>:<CAMERA>"): a resolver returns true and
// fills *bytes (an encoded JPEG or PNG) for the paths it owns, false for the
// others. Every reader above (and ReadImageFile) asks the registered
// resolvers before opening `path` as a file; errors name `path`.
using ImageBytesResolver =
    std::function<bool(const std::string& path, std::vector<uint8_t>* bytes)>;
// Registers `resolver` for the process (thread-safe; each `name` once, a
// second registration under the same name is ignored).
void RegisterImageBytesResolver(const std::string& name,
                                ImageBytesResolver resolver);
// A PNG of `image` (8-bit RGB or gray, 16-bit RGB or gray), in memory.
std::vector<uint8_t> EncodePngImage(const cv::Mat& image);

}  // namespace geodrive
