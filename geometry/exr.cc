#include "geometry/exr.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <exception>
#include <string>
#include <unordered_map>

#include "geometry/util/input_file.h"
#include "geometry/util/size_limits.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// Little-endian integers of the EXR header.
int32_t ReadI32(const uint8_t* p) {
  uint32_t v = 0;
  for (int k = 0; k < 4; ++k) v |= uint32_t{p[k]} << (8 * k);
  return static_cast<int32_t>(v);
}

// Scan lines per chunk of each compression (OpenEXR's ImfCompression.h).
int LinesPerChunk(int compression) {
  switch (compression) {
    case 0:  // NO
    case 1:  // RLE
    case 2:  // ZIPS
      return 1;
    case 3:  // ZIP
    case 5:  // PXR24
      return 16;
    case 9:  // DWAB
      return 256;
    default:  // PIZ, B44, B44A, DWAA
      return 32;
  }
}

// What one part's header declares.
struct ExrPart {
  bool has_window = false;
  int64_t width = 0, height = 0;
  int64_t bytes_per_pixel = 0;  // all channels, as stored
  int compression = 0;
  bool tiled = false;
  int64_t tile_w = 0, tile_h = 0;
  int64_t chunk_count = -1;  // multi-part files declare it
};

// The size of a value of EXR attribute type `type` (OpenEXR's standard
// attribute types), or -1 for types of variable size (strings, channel lists,
// previews, unknown types).
int FixedAttributeSize(const std::string& type) {
  static const std::unordered_map<std::string, int> kSizes = {
      {"int", 4},         {"float", 4},     {"double", 8},
      {"box2i", 16},      {"box2f", 16},    {"v2i", 8},
      {"v2f", 8},         {"v2d", 16},      {"v3i", 12},
      {"v3f", 12},        {"v3d", 24},      {"m33f", 36},
      {"m33d", 72},       {"m44f", 64},     {"m44d", 128},
      {"compression", 1}, {"lineOrder", 1}, {"envmap", 1},
      {"tiledesc", 9},    {"rational", 8},  {"chromaticities", 32},
      {"keycode", 28},    {"timecode", 8},  {"deepImageState", 1}};
  const auto it = kSizes.find(type);
  return it == kSizes.end() ? -1 : it->second;
}

// One part's data window against the limits, and what it adds to the
// chunk table (its tiles or scan-line blocks, or its chunkCount if that is
// more) and to the pixel bytes.
void CheckExrPart(const std::string& path,
                  const ExrPart& p,
                  uint32_t flags,
                  uint64_t* min_chunks,
                  uint64_t* pixel_bytes) {
  GEODRIVE_CHECK_INPUT(p.has_window, path,
                       ": the EXR header has no dataWindow");
  GEODRIVE_CHECK_INPUT(
      p.width >= 1 && p.height >= 1 && p.width <= SizeLimits::kMaxImageSide &&
          p.height <= SizeLimits::kMaxImageSide &&
          p.width * p.height <= SizeLimits::kMaxImagePixels,
      path, ": data window ", p.width, "x", p.height,
      " is outside the reader's limit (1..", SizeLimits::kMaxImageSide,
      " a side, ", SizeLimits::kMaxImagePixels, " pixels)");
  int64_t chunks = 0;
  if (p.tiled || (flags & 0x200)) {
    GEODRIVE_CHECK_INPUT(p.tile_w >= 1 && p.tile_h >= 1 &&
                             p.tile_w <= SizeLimits::kMaxImageSide &&
                             p.tile_h <= SizeLimits::kMaxImageSide,
                         path, ": EXR tiles of ", p.tile_w, "x", p.tile_h,
                         " are outside the reader's limit (1..",
                         SizeLimits::kMaxImageSide, " a side)");
    chunks = ((p.width + p.tile_w - 1) / p.tile_w) *
             ((p.height + p.tile_h - 1) / p.tile_h);
  } else {
    const int lines = LinesPerChunk(p.compression);
    chunks = (p.height + lines - 1) / lines;
  }
  chunks = std::max(chunks, p.chunk_count);
  *min_chunks += static_cast<uint64_t>(std::max<int64_t>(chunks, 0));
  *pixel_bytes += static_cast<uint64_t>(p.width * p.height) *
                  static_cast<uint64_t>(p.bytes_per_pixel);
}

// `n` rounded up to a multiple of `chunk` (>= 1).
int64_t RoundUp(int64_t n, int64_t chunk) {
  return (n + chunk - 1) / chunk * chunk;
}

// OpenEXR sizes its buffers by the chunk, not by the data window, before it
// reads any chunk: a tile's buffer is bytes a pixel x tile width x tile
// height (TiledInputFile), a scan-line block's the window's width x the
// compression's lines per block (ScanLineInputFile), InputFile caches a row
// of tiles (window width x tile height, per channel read), and the
// decompressor holds one or two more of these. A tile or block larger than
// the window costs its whole size, which the window's bytes do not bound
// (tiles of 1x469762048 over a 4x4 window: 1.88 GB from a 369-byte file).
// So the window rounded up to whole chunks, at the part's bytes a pixel, is
// held to the pixel data's ratio: at most SizeLimits::kMaxCompressionRatio
// times the `after_header` bytes, past SizeLimits::kRatioFreeBytes. Tile
// sides are checked by CheckExrPart.
void CheckExrChunkBuffers(const std::string& path,
                          const ExrPart& p,
                          uint32_t flags,
                          uint64_t after_header) {
  const auto check = [&](int64_t w, int64_t h, const std::string& chunks) {
    const uint64_t bytes = SaturatingMul(
        SaturatingMul(static_cast<uint64_t>(w), static_cast<uint64_t>(h)),
        static_cast<uint64_t>(p.bytes_per_pixel));
    const uint64_t ratio = SizeLimits::kMaxCompressionRatio;
    if (bytes <= SizeLimits::kRatioFreeBytes ||
        bytes <= SaturatingMul(after_header, ratio)) {
      return;
    }
    ThrowInputError(path, "EXR data window ", p.width, "x", p.height,
                    " in whole ", chunks, " is ", w, "x", h, " pixels, ", bytes,
                    " bytes at ", p.bytes_per_pixel,
                    " bytes a pixel (OpenEXR's buffers), over ", ratio,
                    " times the ", after_header, " bytes after the header");
  };
  const bool multipart = flags & 0x1000;
  if (p.tiled) {  // a multi-part file's scan-line part may declare tiles
    check(RoundUp(p.width, p.tile_w), RoundUp(p.height, p.tile_h),
          "tiles of " + std::to_string(p.tile_w) + "x" +
              std::to_string(p.tile_h));
  }
  if (multipart || !(flags & 0x200)) {
    const int lines = LinesPerChunk(p.compression);
    check(p.width, RoundUp(p.height, lines),
          "blocks of " + std::to_string(lines) + " scan lines (compression " +
              std::to_string(p.compression) + ")");
  }
}

// Parses the header (every part's attributes) from `head`, the file's first
// bytes, and checks each declared size against the limits and the file's
// `file_size` bytes before OpenEXR sees the file (which sizes its offset table
// and our frame buffer from them). Throws InputError naming `path`.
void CheckExrHeader(const std::string& path) {
  const InputFile in = OpenInputFile(path);
  const uint64_t file_size = in.size();
  std::vector<uint8_t> head(static_cast<size_t>(
      std::min<uint64_t>(file_size, SizeLimits::kMaxExrHeaderBytes)));
  if (!head.empty() && ::pread(in.fd(), head.data(), head.size(), 0) !=
                           static_cast<ssize_t>(head.size())) {
    ThrowInputError(path, "cannot read the EXR header");
  }
  GEODRIVE_CHECK_INPUT(head.size() >= 8 && ReadI32(head.data()) == 20000630,
                       path, ": not a readable EXR file (no EXR magic number)");
  const uint32_t flags = static_cast<uint32_t>(ReadI32(head.data() + 4));
  const bool multipart = flags & 0x1000, deep = flags & 0x800;
  size_t at = 8;
  const auto truncated = [&]() {
    if (file_size > head.size()) {
      ThrowInputError(path, "the EXR header is longer than the limit of ",
                      SizeLimits::kMaxExrHeaderBytes, " bytes");
    }
    ThrowInputError(path, "truncated EXR header (", file_size, " bytes)");
  };
  // A NUL-terminated string at `at`.
  const auto read_string = [&]() {
    const void* end = at < head.size()
                          ? std::memchr(head.data() + at, 0, head.size() - at)
                          : nullptr;
    if (end == nullptr) truncated();
    const size_t n = static_cast<const uint8_t*>(end) - (head.data() + at);
    std::string out(reinterpret_cast<const char*>(head.data() + at), n);
    at += n + 1;
    return out;
  };
  std::vector<ExrPart> parts;
  while (true) {
    ExrPart part;
    while (true) {
      const std::string name = read_string();
      if (name.empty()) break;
      const std::string type = read_string();
      if (at + 4 > head.size()) truncated();
      const int32_t size = ReadI32(head.data() + at);
      at += 4;
      GEODRIVE_CHECK_INPUT(size >= 0, path, ": EXR attribute '", name,
                           "' declares a size of ", size, " bytes");
      if (at + static_cast<uint64_t>(size) > head.size()) truncated();
      // A value of a fixed-size type declares exactly that size: otherwise
      // OpenEXR reads the value's bytes and this parser skips `size`, the
      // two disagree from there on, and OpenEXR acts on attributes this
      // check never saw (a fuzzed chunkCount of 10 bytes made it allocate
      // and clear a huge table).
      const int fixed = FixedAttributeSize(type);
      GEODRIVE_CHECK_INPUT(fixed < 0 || size == fixed, path,
                           ": EXR attribute '", name, "' of type ", type,
                           " declares ", size, " bytes (the type has ", fixed,
                           ")");
      const uint8_t* v = head.data() + at;
      if (name == "dataWindow" && type == "box2i" && size == 16) {
        part.has_window = true;
        part.width = int64_t{ReadI32(v + 8)} - ReadI32(v) + 1;
        part.height = int64_t{ReadI32(v + 12)} - ReadI32(v + 4) + 1;
      } else if (type == "chlist") {
        // Per channel: name, pixel type, pLinear + 3 reserved, x/y sampling;
        // an empty name ends the list. OpenEXR reads the list by this
        // structure, not by `size`: the two must agree, or OpenEXR would go
        // on reading the rest of the header from another place than this
        // check (a fuzzed list made it allocate 1.6 GB for a later value).
        size_t c = 0;
        int bytes_per_pixel = 0;
        while (c < static_cast<size_t>(size) && v[c] != 0) {
          const void* end = std::memchr(v + c, 0, size - c);
          GEODRIVE_CHECK_INPUT(end != nullptr, path,
                               ": malformed EXR channel list");
          c = static_cast<const uint8_t*>(end) - v + 1;
          GEODRIVE_CHECK_INPUT(c + 16 <= static_cast<size_t>(size), path,
                               ": malformed EXR channel list");
          bytes_per_pixel += ReadI32(v + c) == 1 ? 2 : 4;
          c += 16;
        }
        GEODRIVE_CHECK_INPUT(c + 1 == static_cast<size_t>(size), path,
                             ": EXR channel list '", name, "' declares ", size,
                             " bytes but its channels end at byte ", c + 1);
        if (name == "channels") part.bytes_per_pixel += bytes_per_pixel;
      } else if (type == "preview") {
        // Width and height, then 4 bytes a pixel: OpenEXR allocates from
        // the two counts, so they must fill `size` exactly.
        GEODRIVE_CHECK_INPUT(size >= 8, path, ": malformed EXR preview");
        const uint64_t w = static_cast<uint32_t>(ReadI32(v)),
                       h = static_cast<uint32_t>(ReadI32(v + 4));
        GEODRIVE_CHECK_INPUT(w <= (1u << 16) && h <= (1u << 16) &&
                                 8 + 4 * w * h == static_cast<uint64_t>(size),
                             path, ": EXR preview of ", w, "x", h, " declares ",
                             size, " bytes");
      } else if (name == "compression" && type == "compression" && size >= 1) {
        part.compression = v[0];
      } else if (name == "tiles" && type == "tiledesc" && size >= 8) {
        part.tiled = true;
        part.tile_w = static_cast<uint32_t>(ReadI32(v));
        part.tile_h = static_cast<uint32_t>(ReadI32(v + 4));
      } else if (name == "chunkCount" && type == "int" && size == 4) {
        part.chunk_count = ReadI32(v);
      }
      at += static_cast<size_t>(size);
    }
    parts.push_back(part);
    if (!multipart) break;
    if (at < head.size() && head[at] == 0) break;  // the empty header
  }
  const uint64_t header_end = at + (multipart ? 1 : 0);
  const uint64_t after_header =
      file_size > header_end ? file_size - header_end : 0;
  uint64_t min_chunks = 0, pixel_bytes = 0;
  bool uncompressed = true;
  for (const ExrPart& p : parts) {
    CheckExrPart(path, p, flags, &min_chunks, &pixel_bytes);
    uncompressed = uncompressed && p.compression == 0;
  }
  // Each chunk has an 8-byte offset and at least an 8-byte chunk header.
  CheckDeclaredSize(path, "the EXR header's chunk table",
                    SaturatingMul(min_chunks, 16), after_header,
                    std::numeric_limits<uint64_t>::max());
  if (!deep) {  // a deep file's sample counts vary per pixel
    if (uncompressed) {
      CheckDeclaredSize(path, "the EXR data window", pixel_bytes, after_header,
                        std::numeric_limits<uint64_t>::max());
    } else {
      CheckCompressionRatio(path, "the EXR data window", pixel_bytes,
                            after_header);
    }
  }
  // Then what OpenEXR allocates where a chunk is larger than the window.
  for (const ExrPart& p : parts) {
    CheckExrChunkBuffers(path, p, flags, after_header);
  }
}

}  // namespace

std::vector<std::string> ExrChannels(const std::string& path) {
  CheckExrHeader(path);  // OpenEXR opens the path itself
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
  CheckExrHeader(path);  // every size, before OpenEXR or we allocate
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
