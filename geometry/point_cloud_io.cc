// Point cloud files, read and written without PCL io.
//
// Why hand-written: PCL's pcl_io drags in VTK and GDAL (about 300 shared
// libraries, 0.25 s of start-up in every process that links it). Its PLY
// reader fills missing ASCII points with zeros, drops NaN points silently and
// allocates by the declared vertex count before checking the file (a PLY that
// declares 50 M vertices in 80 KB takes 880 MB), and PCL 1.13's PCDReader
// crashes on some malformed headers. No packaged library reads PLY and PCD
// hardened, so these readers are ours: the file is read once (whole, except
// PCD binary points and binary_compressed blocks, which are converted or
// decoded -- by internal/lzf_stream.h; why not liblzf: there -- in chunks as
// they are read), every declared size is
// checked against the file's size before anything is allocated, binary values
// are copied with memcpy per property (in blocks of points, field by field),
// and ASCII values are parsed with std::from_chars.
// Policies (limits, NaN, attribute names): point_cloud_io.h.

#include "geometry/point_cloud_io.h"

#include <fcntl.h>
#include <omp.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <memory>
#include <new>
#include <string_view>
#include <type_traits>
#include <vector>

#include "geometry/internal/lzf_stream.h"
#include "geometry/util/files.h"
#include "geometry/util/input_file.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__,
              "the binary readers assume a little-endian host");
static_assert(sizeof(float) == 4 && sizeof(double) == 8, "IEEE floats");
static_assert(sizeof(Eigen::Vector3f) == 12 && sizeof(Color3u8) == 3,
              "positions and colours are packed arrays");

// ---------------------------------------------------------------------------
// Whole files.

struct FileBuffer {
  std::unique_ptr<char[]> bytes;
  size_t size = 0;
  const char* begin() const { return bytes.get(); }
  const char* end() const { return bytes.get() + size; }
};

// OpenMP threads a reader spreads one file's work over: OpenMP's default
// count, or 1 inside a parallel region (the caller already spreads its work).
int ReaderThreads() { return omp_in_parallel() ? 1 : omp_get_max_threads(); }

// A regular file read from its start into an uninitialised buffer (no zero
// fill) as far as the reader needs (Buffer, ReadAll), then, where a reader
// wants it, streamed on from an offset inside that buffer (Seek, ReadNext)
// without holding the rest: PCD binary points and LZF blocks, 160 MB less
// memory and as many fewer page faults at 10 M points.
class FileReader {
 public:
  // Opens `path` and buffers its first `first_bytes` (or all of it).
  FileReader(const std::string& path, size_t first_bytes) : path_(path) {
    InputFile input = OpenInputFile(path);
    size_ = input.size();
    fd_ = input.Release();
    Buffer(std::min<uint64_t>(size_, first_bytes));
  }
  ~FileReader() { ::close(fd_); }
  FileReader(const FileReader&) = delete;
  FileReader& operator=(const FileReader&) = delete;

  uint64_t size() const { return size_; }
  // The buffered bytes: the file's first buffered() bytes.
  const char* begin() const { return bytes_.get(); }
  size_t buffered() const { return buffered_; }

  // Buffers the file's first `n` bytes (n <= size()), before any streaming.
  // Throws when they do not fit in memory or cannot be read.
  void Buffer(uint64_t n) {
    if (bytes_ && n <= buffered_) return;
    if (!bytes_ || n > capacity_) {  // never null, even for an empty file
      std::unique_ptr<char[]> grown;
      try {
        grown.reset(new char[n + 1]);
      } catch (const std::bad_alloc&) {
        ThrowInputError(path_, "file of ", size_,
                        " bytes does not fit in memory");
      }
      if (buffered_ > 0) std::memcpy(grown.get(), bytes_.get(), buffered_);
      bytes_ = std::move(grown);
      capacity_ = n;
    }
    if (!ReadInParallel(bytes_.get() + buffered_, n - buffered_, buffered_))
      ThrowReadError();
    buffered_ = n;
  }
  void ReadAll() { Buffer(size_); }
  // The whole file (after ReadAll), taken.
  FileBuffer Take() {
    FileBuffer file;
    file.bytes = std::move(bytes_);
    file.size = buffered_;
    return file;
  }

  // Streaming: ReadNext reads on from file offset `offset` (<= buffered()),
  // from the buffer first, then from the file.
  void Seek(uint64_t offset) { position_ = std::min(offset, buffered_); }
  // Reads the next n bytes into dst; false when the file ends first or a
  // read fails (ThrowReadError says which).
  bool ReadNext(uint8_t* dst, size_t n) {
    char* out = reinterpret_cast<char*>(dst);
    if (position_ < buffered_) {
      const size_t k =
          static_cast<size_t>(std::min<uint64_t>(n, buffered_ - position_));
      std::memcpy(out, bytes_.get() + position_, k);
      position_ += k;
      out += k;
      n -= k;
    }
    if (n == 0) return true;
    // Here position_ is the file's read position: Buffer reads the file in
    // order, a Seek never goes past buffered(), and streaming comes last.
    if (!Read(out, n)) return false;
    position_ += n;
    return true;
  }
  [[noreturn]] void ThrowReadError() const {
    if (read_error_ != 0) {
      ThrowInputError(path_, "cannot read (", std::strerror(read_error_), ")");
    }
    ThrowInputError(path_, "file shrank while it was read");
  }

 private:
  // Reads exactly n bytes at file offset `offset`, the file's read position,
  // and leaves the read position after them. Large reads are split over
  // OpenMP's threads (pread of one part each): copying a file out of the page
  // cache, and first touching the pages it is copied to, is CPU work in the
  // kernel, and a 451 MB ASCII PLY spent about a third of its load's wall
  // time in one thread's read before the parse could start on all of them.
  bool ReadInParallel(char* dst, size_t n, uint64_t offset) {
    constexpr size_t kPart = size_t{16} << 20;
    const int threads = ReaderThreads();
    if (threads <= 1 || n < 2 * kPart) return Read(dst, n);
    const int64_t parts = static_cast<int64_t>((n + kPart - 1) / kPart);
    std::vector<int> errors(static_cast<size_t>(parts), 0);
    std::vector<uint8_t> short_read(static_cast<size_t>(parts), 0);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (int64_t k = 0; k < parts; ++k) {
      size_t at = static_cast<size_t>(k) * kPart;
      const size_t end = std::min(n, at + kPart);
      while (at < end) {
        const ssize_t r =
            ::pread(fd_, dst + at, end - at, static_cast<off_t>(offset + at));
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) {
          errors[k] = r < 0 ? errno : 0;
          short_read[k] = 1;
          break;
        }
        at += static_cast<size_t>(r);
      }
    }
    // The first part that failed says why, as the serial read would.
    for (int64_t k = 0; k < parts; ++k) {
      if (short_read[k]) {
        read_error_ = errors[k];
        return false;
      }
    }
    if (::lseek(fd_, static_cast<off_t>(offset + n), SEEK_SET) < 0) {
      read_error_ = errno;
      return false;
    }
    return true;
  }

  // Reads exactly n bytes at the file's read position.
  bool Read(char* dst, size_t n) {
    while (n > 0) {
      const ssize_t r = ::read(fd_, dst, n);
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) {
        read_error_ = r < 0 ? errno : 0;
        return false;
      }
      dst += r;
      n -= static_cast<size_t>(r);
    }
    return true;
  }

  const std::string& path_;
  uint64_t size_ = 0;
  int fd_ = -1;
  std::unique_ptr<char[]> bytes_;
  uint64_t capacity_ = 0;
  uint64_t buffered_ = 0;
  uint64_t position_ = 0;
  int read_error_ = 0;
};

// Reads a whole regular file.
FileBuffer ReadWholeFile(const std::string& path) {
  FileReader file(path, 0);
  file.ReadAll();
  return file.Take();
}

// Printable excerpt of untrusted bytes for an error message.
std::string Excerpt(const char* b, const char* e, size_t max_len = 40) {
  std::string out;
  for (const char* p = b; p < e && out.size() < max_len; ++p) {
    const unsigned char c = static_cast<unsigned char>(*p);
    out += (c >= 32 && c < 127) ? static_cast<char>(c) : '?';
  }
  if (static_cast<size_t>(e - b) > max_len) out += "...";
  return out;
}
std::string Excerpt(std::string_view s, size_t max_len = 40) {
  return Excerpt(s.data(), s.data() + s.size(), max_len);
}

// Lines of text ending at '\n' ('\r' before it is whitespace).
struct Line {
  const char* b = nullptr;
  const char* e = nullptr;
  uint64_t number = 0;  // 1-based line number in the file
};

inline bool IsBlank(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

class LineReader {
 public:
  LineReader(const char* p, const char* end, uint64_t lines_before)
      : p_(p), end_(end), number_(lines_before) {}
  // The next line (blank lines included); false at the end of the data.
  bool NextAny(Line* line) {
    if (p_ >= end_) return false;
    const void* nl = std::memchr(p_, '\n', static_cast<size_t>(end_ - p_));
    const char* e = nl ? static_cast<const char*>(nl) : end_;
    *line = Line{p_, e, ++number_};
    p_ = nl ? e + 1 : end_;
    return true;
  }
  // The next line that is not blank, leading whitespace skipped.
  bool Next(Line* line) {
    while (NextAny(line)) {
      while (line->b < line->e && IsBlank(*line->b)) ++line->b;
      if (line->b < line->e) return true;
    }
    return false;
  }
  // Start of the bytes after the lines read so far.
  const char* position() const { return p_; }
  // Lines read so far, counted from the start of the file.
  uint64_t number() const { return number_; }

 private:
  const char* p_;
  const char* end_;
  uint64_t number_;
};

// Splits the next whitespace-separated token off [*p, e).
inline bool NextToken(const char** p, const char* e, std::string_view* token) {
  const char* q = *p;
  while (q < e && IsBlank(*q)) ++q;
  if (q == e) {
    *p = q;
    return false;
  }
  const char* b = q;
  while (q < e && !IsBlank(*q)) ++q;
  *token = std::string_view(b, static_cast<size_t>(q - b));
  *p = q;
  return true;
}

std::vector<std::string_view> Tokens(const Line& line) {
  std::vector<std::string_view> tokens;
  const char* p = line.b;
  std::string_view token;
  while (NextToken(&p, line.e, &token)) tokens.push_back(token);
  return tokens;
}

// Unsigned decimal count (digits only, at most `max`).
bool ParseCount(std::string_view token, uint64_t max, uint64_t* value) {
  if (token.empty() || token.size() > 20) return false;
  if (token.size() <= 19) {
    // At most 19 digits cannot overflow 64 bits: summed inline (the colour
    // channels of an ASCII row are three such tokens; from_chars was a tenth
    // of a 10 M-point read).
    uint64_t v = 0;
    for (char c : token) {
      const unsigned digit = static_cast<unsigned char>(c) - unsigned{'0'};
      if (digit > 9) return false;
      v = 10 * v + digit;
    }
    *value = v;
    return v <= max;
  }
  for (char c : token) {
    if (c < '0' || c > '9') return false;
  }
  const auto r =
      std::from_chars(token.data(), token.data() + token.size(), *value);
  return r.ec == std::errc() && *value <= max;
}

// ---------------------------------------------------------------------------
// Scalar types and what each field of a file becomes.

enum class Scalar : uint8_t {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kInt64,
  kUint64,
  kFloat32,
  kFloat64,
};

size_t SizeOf(Scalar s) {
  static constexpr size_t kSizes[] = {1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
  return kSizes[static_cast<int>(s)];
}
bool IsFloat(Scalar s) {
  return s == Scalar::kFloat32 || s == Scalar::kFloat64;
}

enum class Target : uint8_t {
  kSkip,
  kX,
  kY,
  kZ,
  kPackedRgb,
  kRed,
  kGreen,
  kBlue,
  kInstanceId,
  // The float columns (ScalarColumn) from here on.
  kConfidence,
  kIntensity,
  kRing,
  kFootprint,
  // footprint_u (x, y, z), then footprint_v: six consecutive targets.
  kFootprintUx,
  kFootprintUy,
  kFootprintUz,
  kFootprintVx,
  kFootprintVy,
  kFootprintVz,
};
constexpr int kNumTargets = static_cast<int>(Target::kFootprintVz) + 1;

constexpr bool IsFloatColumn(Target t) { return t >= Target::kConfidence; }

// The footprint axes' PLY properties / PCD fields, in file order.
constexpr const char* kFootprintAxisNames[] = {"footprint_ux", "footprint_uy",
                                               "footprint_uz", "footprint_vx",
                                               "footprint_vy", "footprint_vz"};

// A PLY property or a PCD field.
struct FieldSpec {
  std::string name;
  std::string type_name;  // as the file spells it (PLY) or e.g. "F 4" (PCD)
  Scalar type = Scalar::kFloat32;
  uint64_t count = 1;  // PCD COUNT: values per point
  bool is_list = false;
  Scalar list_count_type = Scalar::kUint8;
  Target target = Target::kSkip;

  size_t Bytes() const { return SizeOf(type) * static_cast<size_t>(count); }
};

// Picks what each field becomes (point_cloud_io.h, "Attributes"). `what` is
// "property" (PLY) or "field" (PCD).
void AssignTargets(const std::string& path,
                   const char* what,
                   std::vector<FieldSpec>* fields) {
  auto find = [&](std::string_view name) -> FieldSpec* {
    FieldSpec* found = nullptr;
    for (FieldSpec& f : *fields) {
      if (f.name != name) continue;
      if (found) ThrowInputError(path, "duplicate ", what, " '", name, "'");
      found = &f;
    }
    return found;
  };
  auto usable = [](const FieldSpec* f) {
    return f && !f->is_list && f->count == 1;
  };
  const Target axes[] = {Target::kX, Target::kY, Target::kZ};
  const char* axis_names[] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    FieldSpec* f = find(axis_names[k]);
    if (!f)
      ThrowInputError(path, "no x/y/z ", what, "s (", axis_names[k],
                      " is missing)");
    if (!usable(f) || !IsFloat(f->type)) {
      ThrowInputError(path, what, " '", axis_names[k],
                      "' must be one float or double value (it is ",
                      f->is_list ? "a list" : f->type_name.c_str(),
                      f->count != 1 ? " with COUNT > 1" : "", ")");
    }
    f->target = axes[k];
  }
  FieldSpec* packed = find("rgb");
  FieldSpec* rgba = find("rgba");
  if (!(usable(packed) && packed->Bytes() == 4)) packed = rgba;
  if (usable(packed) && packed->Bytes() == 4) {
    packed->target = Target::kPackedRgb;
  } else {
    const char* sets[][3] = {{"red", "green", "blue"},
                             {"diffuse_red", "diffuse_green", "diffuse_blue"},
                             {"r", "g", "b"}};
    for (const auto& set : sets) {
      FieldSpec* c[3] = {find(set[0]), find(set[1]), find(set[2])};
      if (usable(c[0]) && usable(c[1]) && usable(c[2])) {
        c[0]->target = Target::kRed;
        c[1]->target = Target::kGreen;
        c[2]->target = Target::kBlue;
        break;
      }
    }
  }
  const std::pair<const char*, Target> scalars[] = {
      {"confidence", Target::kConfidence},
      {"instance_id", Target::kInstanceId},
      {"intensity", Target::kIntensity},
      {"ring", Target::kRing}};
  for (const auto& [name, target] : scalars) {
    FieldSpec* f = find(name);
    if (usable(f)) f->target = target;
  }
  // Capture footprints as WritePly/WritePcd store them: `footprint`, and the
  // footprint axes only as all six footprint_{u,v}{x,y,z} next to it.
  FieldSpec* footprint = find("footprint");
  if (!usable(footprint)) return;
  footprint->target = Target::kFootprint;
  FieldSpec* axes_found[6];
  for (int k = 0; k < 6; ++k) {
    axes_found[k] = find(kFootprintAxisNames[k]);
    if (!usable(axes_found[k])) return;
  }
  for (int k = 0; k < 6; ++k) {
    axes_found[k]->target =
        static_cast<Target>(static_cast<int>(Target::kFootprintUx) + k);
  }
}

// Raw pointers into the arrays of the cloud being read.
struct CloudColumns {
  float* positions = nullptr;  // x y z per point
  uint8_t* colors = nullptr;   // r g b per point
  float* confidence = nullptr;
  int32_t* instance_ids = nullptr;
  float* intensity = nullptr;
  float* ring = nullptr;
  float* footprints = nullptr;
  float* footprint_u = nullptr;  // x y z per point
  float* footprint_v = nullptr;
};

// The float column of a scalar target and, for the footprint axes, the
// stride (3) and offset of its component.
float* ScalarColumn(Target target, const CloudColumns& out, size_t* stride) {
  *stride = 1;
  switch (target) {
    case Target::kConfidence:
      return out.confidence;
    case Target::kIntensity:
      return out.intensity;
    case Target::kRing:
      return out.ring;
    case Target::kFootprint:
      return out.footprints;
    default:
      break;
  }
  const int k =
      static_cast<int>(target) - static_cast<int>(Target::kFootprintUx);
  *stride = 3;
  return (k < 3 ? out.footprint_u : out.footprint_v) + k % 3;
}

// Sizes `cloud` for `n` points and the attributes `fields` map to.
CloudColumns AllocateCloud(size_t n,
                           const std::vector<FieldSpec>& fields,
                           PointCloud* cloud) {
  bool has[kNumTargets] = {};
  for (const FieldSpec& f : fields) has[static_cast<int>(f.target)] = true;
  auto want = [&](Target t) { return has[static_cast<int>(t)]; };
  CloudColumns out;
  cloud->positions.resize(n);  // Eigen's default constructor: no zero fill
  out.positions = n ? cloud->positions[0].data() : nullptr;
  if (want(Target::kPackedRgb) || want(Target::kRed)) {
    cloud->colors.resize(n);
    out.colors = n ? cloud->colors[0].data() : nullptr;
  }
  if (want(Target::kConfidence)) {
    cloud->confidence.resize(n);
    out.confidence = cloud->confidence.data();
  }
  if (want(Target::kInstanceId)) {
    cloud->instance_ids.resize(n);
    out.instance_ids = cloud->instance_ids.data();
  }
  if (want(Target::kIntensity)) {
    cloud->intensity.resize(n);
    out.intensity = cloud->intensity.data();
  }
  if (want(Target::kRing)) {
    cloud->ring.resize(n);
    out.ring = cloud->ring.data();
  }
  if (want(Target::kFootprint)) {
    cloud->footprints.resize(n);
    out.footprints = cloud->footprints.data();
  }
  if (want(Target::kFootprintUx)) {  // AssignTargets: all six or none
    cloud->footprint_u.resize(n);
    cloud->footprint_v.resize(n);
    out.footprint_u = n ? cloud->footprint_u[0].data() : nullptr;
    out.footprint_v = n ? cloud->footprint_v[0].data() : nullptr;
  }
  return out;
}

// ---------------------------------------------------------------------------
// Value conversions (the same for binary and ASCII input).

template <typename T>
inline T ByteSwapped(T v) {
  if constexpr (sizeof(T) == 1) {
    return v;
  } else {
    using U = std::conditional_t<
        sizeof(T) == 2, uint16_t,
        std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>;
    U u;
    std::memcpy(&u, &v, sizeof(T));
    if constexpr (sizeof(T) == 2) u = __builtin_bswap16(u);
    if constexpr (sizeof(T) == 4) u = __builtin_bswap32(u);
    if constexpr (sizeof(T) == 8) u = __builtin_bswap64(u);
    std::memcpy(&v, &u, sizeof(T));
    return v;
  }
}

template <typename T, bool kSwap>
inline T Load(const char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  if constexpr (kSwap) v = ByteSwapped(v);
  return v;
}

template <typename T>
inline float ToFloat(T v) {
  if constexpr (std::is_same_v<T, float>) {
    return v;
  } else {
    return static_cast<float>(static_cast<double>(v));
  }
}

// A colour channel: rounded and clamped to 0..255 (NaN becomes 0).
template <typename T>
inline uint8_t ToChannel(T v) {
  if constexpr (std::is_floating_point_v<T>) {
    const double d = v;
    if (!(d > 0)) return 0;
    if (d >= 255) return 255;
    return static_cast<uint8_t>(std::lround(d));
  } else if constexpr (std::is_signed_v<T>) {
    return static_cast<uint8_t>(v < 0 ? 0 : (v > 255 ? 255 : v));
  } else {
    return static_cast<uint8_t>(v > 255 ? 255 : v);
  }
}

// Truncates toward zero (as a C++ cast); false outside the int32 range.
template <typename T>
inline bool ToInstanceId(T v, int32_t* out) {
  const double d = static_cast<double>(v);
  if (!(d > -2147483649.0 && d < 2147483648.0)) return false;
  *out = static_cast<int32_t>(d);
  return true;
}

[[noreturn]] void ThrowInstanceIdRange(const std::string& path,
                                       size_t point,
                                       double value) {
  ThrowInputError(path, "point ", point, " has instance_id ", value,
                  ", outside the int32 range");
}

inline void StorePackedRgb(uint32_t bits, uint8_t* rgb) {
  rgb[0] = static_cast<uint8_t>(bits >> 16);
  rgb[1] = static_cast<uint8_t>(bits >> 8);
  rgb[2] = static_cast<uint8_t>(bits);
}

// Stores one value of point `i` (ASCII and variable-size binary records).
void StoreValue(const std::string& path,
                Target target,
                size_t i,
                double v,
                const CloudColumns& out) {
  if (IsFloatColumn(target)) {
    size_t stride;
    ScalarColumn(target, out, &stride)[stride * i] = static_cast<float>(v);
    return;
  }
  switch (target) {
    case Target::kX:
    case Target::kY:
    case Target::kZ:
      out.positions[3 * i +
                    (static_cast<int>(target) - static_cast<int>(Target::kX))] =
          static_cast<float>(v);
      return;
    case Target::kRed:
    case Target::kGreen:
    case Target::kBlue:
      out.colors[3 * i + (static_cast<int>(target) -
                          static_cast<int>(Target::kRed))] = ToChannel(v);
      return;
    case Target::kInstanceId:
      if (!ToInstanceId(v, &out.instance_ids[i]))
        ThrowInstanceIdRange(path, i, v);
      return;
    case Target::kPackedRgb:  // stored through StorePackedRgb
    case Target::kSkip:
    default:  // the float columns, stored above
      return;
  }
}

// Converts `n` values of type T (points first .. first + n - 1), `stride`
// bytes apart from `src`, into the column of `target`.
template <typename T, bool kSwap>
void ConvertColumn(const std::string& path,
                   const char* src,
                   size_t stride,
                   size_t first,
                   size_t n,
                   Target target,
                   const CloudColumns& out) {
  if (IsFloatColumn(target)) {
    size_t step;
    float* dst = ScalarColumn(target, out, &step) + step * first;
    for (size_t i = 0; i < n; ++i)
      dst[step * i] = ToFloat(Load<T, kSwap>(src + i * stride));
    return;
  }
  switch (target) {
    case Target::kX:
    case Target::kY:
    case Target::kZ: {
      float* dst = out.positions + 3 * first +
                   (static_cast<int>(target) - static_cast<int>(Target::kX));
      for (size_t i = 0; i < n; ++i)
        dst[3 * i] = ToFloat(Load<T, kSwap>(src + i * stride));
      return;
    }
    case Target::kRed:
    case Target::kGreen:
    case Target::kBlue: {
      uint8_t* dst =
          out.colors + 3 * first +
          (static_cast<int>(target) - static_cast<int>(Target::kRed));
      for (size_t i = 0; i < n; ++i)
        dst[3 * i] = ToChannel(Load<T, kSwap>(src + i * stride));
      return;
    }
    case Target::kPackedRgb:
      if constexpr (sizeof(T) == 4) {
        uint8_t* dst = out.colors + 3 * first;
        for (size_t i = 0; i < n; ++i) {
          StorePackedRgb(Load<uint32_t, kSwap>(src + i * stride), dst + 3 * i);
        }
      }
      return;
    case Target::kInstanceId: {
      int32_t* dst = out.instance_ids + first;
      for (size_t i = 0; i < n; ++i) {
        const T v = Load<T, kSwap>(src + i * stride);
        if (!ToInstanceId(v, dst + i))
          ThrowInstanceIdRange(path, first + i, static_cast<double>(v));
      }
      return;
    }
    case Target::kSkip:
    default:  // the float columns, stored above
      return;
  }
}

using ColumnFn = void (*)(const std::string&,
                          const char*,
                          size_t,
                          size_t,
                          size_t,
                          Target,
                          const CloudColumns&);

template <bool kSwap>
ColumnFn ColumnFunctionFor(Scalar type) {
  switch (type) {
    case Scalar::kInt8:
      return &ConvertColumn<int8_t, kSwap>;
    case Scalar::kUint8:
      return &ConvertColumn<uint8_t, kSwap>;
    case Scalar::kInt16:
      return &ConvertColumn<int16_t, kSwap>;
    case Scalar::kUint16:
      return &ConvertColumn<uint16_t, kSwap>;
    case Scalar::kInt32:
      return &ConvertColumn<int32_t, kSwap>;
    case Scalar::kUint32:
      return &ConvertColumn<uint32_t, kSwap>;
    case Scalar::kInt64:
      return &ConvertColumn<int64_t, kSwap>;
    case Scalar::kUint64:
      return &ConvertColumn<uint64_t, kSwap>;
    case Scalar::kFloat32:
      return &ConvertColumn<float, kSwap>;
    case Scalar::kFloat64:
      return &ConvertColumn<double, kSwap>;
  }
  return nullptr;
}

// One mapped field of fixed-layout binary data: value of point i at
// base + i * stride.
struct Column {
  const char* base;
  size_t stride;
  Target target;
  ColumnFn convert;
};

// Converts fixed-layout binary data block by block (a block of points stays
// in cache while each field is copied out of it).
// Converts n points whose records start at each column's base into the
// cloud's points first_point, first_point + 1, ...
void ConvertColumns(const std::string& path,
                    const std::vector<Column>& columns,
                    size_t n,
                    const CloudColumns& out,
                    size_t first_point = 0) {
  constexpr size_t kBlock = 4096;
  for (size_t first = 0; first < n; first += kBlock) {
    const size_t m = std::min(kBlock, n - first);
    for (const Column& c : columns) {
      c.convert(path, c.base + first * c.stride, c.stride, first_point + first,
                m, c.target, out);
    }
  }
}

// One value of `type` at p, as a double (variable-size binary records).
double LoadNumber(const char* p, Scalar type, bool swap) {
  switch (type) {
    case Scalar::kInt8:
      return Load<int8_t, false>(p);
    case Scalar::kUint8:
      return Load<uint8_t, false>(p);
    case Scalar::kInt16:
      return swap ? Load<int16_t, true>(p) : Load<int16_t, false>(p);
    case Scalar::kUint16:
      return swap ? Load<uint16_t, true>(p) : Load<uint16_t, false>(p);
    case Scalar::kInt32:
      return swap ? Load<int32_t, true>(p) : Load<int32_t, false>(p);
    case Scalar::kUint32:
      return swap ? Load<uint32_t, true>(p) : Load<uint32_t, false>(p);
    case Scalar::kInt64:
      return static_cast<double>(swap ? Load<int64_t, true>(p)
                                      : Load<int64_t, false>(p));
    case Scalar::kUint64:
      return static_cast<double>(swap ? Load<uint64_t, true>(p)
                                      : Load<uint64_t, false>(p));
    case Scalar::kFloat32:
      return swap ? Load<float, true>(p) : Load<float, false>(p);
    case Scalar::kFloat64:
      return swap ? Load<double, true>(p) : Load<double, false>(p);
  }
  return 0;
}

// ---------------------------------------------------------------------------
// ASCII values.

enum class Parse { kOk, kBad, kOutOfRange };

template <typename T>
Parse ParseInteger(const char* b, const char* e, T* v) {
  const auto r = std::from_chars(b, e, *v);
  if (r.ptr != e ||
      (r.ec != std::errc() && r.ec != std::errc::result_out_of_range)) {
    return Parse::kBad;
  }
  return r.ec == std::errc() ? Parse::kOk : Parse::kOutOfRange;
}

template <typename T>
Parse ParseFloating(const char* b, const char* e, T* v) {
  const auto r = std::from_chars(b, e, *v);
  if (r.ptr != e) return Parse::kBad;
  if (r.ec == std::errc()) return Parse::kOk;
  if (r.ec != std::errc::result_out_of_range) return Parse::kBad;
  // Underflow is a zero or a denormal, not an error; overflow is.
  long double wide = 0;
  const auto w = std::from_chars(b, e, wide);
  if (w.ec == std::errc() && w.ptr == e && std::fabs(wide) < 1) {
    *v = static_cast<T>(wide);
    return Parse::kOk;
  }
  return Parse::kOutOfRange;
}

// Parses `token` as a value of `type` (an optional leading '+' is allowed).
Parse ParseNumber(std::string_view token, Scalar type, double* value) {
  const char* b = token.data();
  const char* e = b + token.size();
  if (e - b > 1 && *b == '+' && b[1] != '-' && b[1] != '+') ++b;
  switch (type) {
    case Scalar::kFloat32: {
      float f = 0;
      const Parse p = ParseFloating(b, e, &f);
      *value = f;
      return p;
    }
    case Scalar::kFloat64:
      return ParseFloating(b, e, value);
    case Scalar::kUint64: {
      uint64_t u = 0;
      if (b < e && *b == '-') {
        int64_t s;
        return ParseInteger(b, e, &s) == Parse::kBad ? Parse::kBad
                                                     : Parse::kOutOfRange;
      }
      const Parse p = ParseInteger(b, e, &u);
      *value = static_cast<double>(u);
      return p;
    }
    default: {
      int64_t s;
      const Parse p = ParseInteger(b, e, &s);
      if (p != Parse::kOk) return p;
      int64_t lo = std::numeric_limits<int64_t>::min();
      int64_t hi = std::numeric_limits<int64_t>::max();
      switch (type) {
        case Scalar::kInt8:
          lo = -128, hi = 127;
          break;
        case Scalar::kUint8:
          lo = 0, hi = 255;
          break;
        case Scalar::kInt16:
          lo = -32768, hi = 32767;
          break;
        case Scalar::kUint16:
          lo = 0, hi = 65535;
          break;
        case Scalar::kInt32:
          lo = std::numeric_limits<int32_t>::min();
          hi = std::numeric_limits<int32_t>::max();
          break;
        case Scalar::kUint32:
          lo = 0, hi = std::numeric_limits<uint32_t>::max();
          break;
        default:
          break;
      }
      if (s < lo || s > hi) return Parse::kOutOfRange;
      *value = static_cast<double>(s);
      return Parse::kOk;
    }
  }
}

// The packed colour of an ASCII token: an unsigned integer is the uint32
// itself (PCL 1.13 writes rgb so, even for TYPE F); otherwise a float field's
// value is reinterpreted (older PCL wrote the float).
Parse ParsePackedRgb(std::string_view token, Scalar type, uint32_t* bits) {
  if (type == Scalar::kFloat32 &&
      token.find_first_not_of("0123456789") != std::string_view::npos) {
    float f = 0;
    const Parse p =
        ParseFloating(token.data(), token.data() + token.size(), &f);
    std::memcpy(bits, &f, 4);
    return p;
  }
  double v = 0;
  const Parse p =
      ParseNumber(token, type == Scalar::kFloat32 ? Scalar::kUint32 : type, &v);
  *bits = static_cast<uint32_t>(static_cast<int64_t>(v));
  return p;
}

[[noreturn]] void ThrowBadAsciiValue(const std::string& path,
                                     const Line& line,
                                     std::string_view token,
                                     const FieldSpec& f,
                                     const char* what,
                                     bool list_length,
                                     Parse result) {
  const std::string type = list_length ? "list length" : f.type_name;
  if (result == Parse::kOutOfRange) {
    ThrowInputError(path, "line ", line.number, ": value '", Excerpt(token),
                    "' is out of range for ", what, " '", f.name, "' (", type,
                    ")");
  }
  ThrowInputError(path, "line ", line.number, ": bad value '", Excerpt(token),
                  "' for ", what, " '", f.name, "' (", type, ")");
}

// Parses one ASCII line holding the values of `fields` for point `i` (a PLY
// vertex or a PCD point). `what` is "property" or "field".
void ParseAsciiRow(const std::string& path,
                   const Line& line,
                   const std::vector<FieldSpec>& fields,
                   const char* what,
                   size_t i,
                   const CloudColumns& out) {
  const char* p = line.b;
  std::string_view token;
  auto next = [&](const FieldSpec& f) {
    if (!NextToken(&p, line.e, &token)) {
      ThrowInputError(path, "line ", line.number,
                      ": too few values (the line ends before ", what, " '",
                      f.name, "')");
    }
  };
  for (const FieldSpec& f : fields) {
    uint64_t values = f.count;
    if (f.is_list) {
      next(f);
      double length;
      const Parse r = ParseNumber(token, f.list_count_type, &length);
      if (r != Parse::kOk || length < 0) {
        ThrowBadAsciiValue(path, line, token, f, what, true,
                           r == Parse::kOk ? Parse::kOutOfRange : r);
      }
      values = static_cast<uint64_t>(length);
    }
    for (uint64_t k = 0; k < values; ++k) {
      next(f);
      if (f.target == Target::kPackedRgb) {
        uint32_t bits;
        const Parse r = ParsePackedRgb(token, f.type, &bits);
        if (r != Parse::kOk)
          ThrowBadAsciiValue(path, line, token, f, what, false, r);
        StorePackedRgb(bits, out.colors + 3 * i);
        continue;
      }
      double v;
      const Parse r = ParseNumber(token, f.type, &v);
      if (r != Parse::kOk)
        ThrowBadAsciiValue(path, line, token, f, what, false, r);
      if (f.target != Target::kSkip) StoreValue(path, f.target, i, v, out);
    }
  }
  if (NextToken(&p, line.e, &token)) {
    ThrowInputError(path, "line ", line.number, ": too many values ('",
                    Excerpt(token), "' after the last ", what, ")");
  }
}

// The fast path of ASCII rows, for the common layouts (float32 values into
// float columns, uint8 colour channels, rgb packed as an unsigned integer):
// each value parsed straight into its column. Any other layout, and any
// token it does not take as it stands (a bad or out-of-range value, a float
// that underflows, a packed rgb written as a float), goes to ParseAsciiRow,
// which stores the same values or throws the error.
struct FastAsciiField {
  enum Kind : uint8_t { kFloat, kChannel, kPackedRgb };
  Kind kind;
  float* floats;   // kFloat: point i's value at floats[stride * i]
  uint8_t* bytes;  // kChannel: bytes[3 * i]; kPackedRgb: bytes[3 * i + 0..2]
  size_t stride;
};

// The fast fields of a layout, or none when some field needs the general
// path.
std::vector<FastAsciiField> FastAsciiFields(
    const std::vector<FieldSpec>& fields, const CloudColumns& out) {
  std::vector<FastAsciiField> fast;
  // No points (the columns are null): no rows to parse.
  if (!out.positions) return fast;
  for (const FieldSpec& f : fields) {
    if (f.is_list || f.count != 1) return {};
    const int t = static_cast<int>(f.target);
    if (f.type == Scalar::kFloat32 && f.target >= Target::kX &&
        f.target <= Target::kZ) {
      fast.push_back({FastAsciiField::kFloat,
                      out.positions + (t - static_cast<int>(Target::kX)),
                      nullptr, 3});
    } else if (f.type == Scalar::kFloat32 && IsFloatColumn(f.target)) {
      size_t stride;
      float* column = ScalarColumn(f.target, out, &stride);
      fast.push_back({FastAsciiField::kFloat, column, nullptr, stride});
    } else if (f.type == Scalar::kUint8 && f.target >= Target::kRed &&
               f.target <= Target::kBlue) {
      fast.push_back({FastAsciiField::kChannel, nullptr,
                      out.colors + (t - static_cast<int>(Target::kRed)), 3});
    } else if ((f.type == Scalar::kUint32 || f.type == Scalar::kFloat32) &&
               f.target == Target::kPackedRgb) {
      fast.push_back({FastAsciiField::kPackedRgb, nullptr, out.colors, 3});
    } else {
      return {};
    }
  }
  return fast;
}

// A float32 token in the short decimal form ASCII clouds are written in:
// '-'?, digits, optionally '.' and digits, optionally an exponent, at most 19
// digits in all. Clinger's fast path: when the digits as an integer m are at
// most 2^53 and the power of ten p within 10^+-22, both are exact doubles and
// one IEEE multiplication or division gives d, the double nearest m * 10^p.
// d then rounds to the float nearest m * 10^p unless d is exactly halfway
// between two floats (a float midpoint is a double, so the exact value and d
// lie on the same side of every other midpoint). False for anything else --
// another form, a case the fast path cannot round exactly, a midpoint --
// which std::from_chars then decides. Hand-written because
// from_chars (a library call per token) took a quarter of a 10 M-point ASCII
// read; the result is the same float.
bool ParseFloatFast(const char* b, const char* e, float* out) {
  static constexpr double kPow10[23] = {
      1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
      1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  const char* p = b;
  const bool negative = p < e && *p == '-';
  p += negative;
  uint64_t m = 0;
  const char* digits_begin = p;
  while (p < e && static_cast<unsigned>(*p - '0') <= 9)
    m = 10 * m + (*p++ - '0');
  if (p == digits_begin) return false;
  int fraction = 0;
  if (p < e && *p == '.') {
    const char* f = ++p;
    while (p < e && static_cast<unsigned>(*p - '0') <= 9)
      m = 10 * m + (*p++ - '0');
    fraction = static_cast<int>(p - f);
    if (fraction == 0) return false;
  }
  // 19 digits cannot overflow m.
  if (p - digits_begin - (fraction > 0) > 19) return false;
  int exponent = 0;
  if (p < e && (*p == 'e' || *p == 'E')) {
    ++p;
    const bool exponent_negative = p < e && *p == '-';
    if (p < e && (*p == '-' || *p == '+')) ++p;
    const char* x = p;
    while (p < e && p - x < 4 && static_cast<unsigned>(*p - '0') <= 9)
      exponent = 10 * exponent + (*p++ - '0');
    if (p == x) return false;
    if (exponent_negative) exponent = -exponent;
  }
  if (p != e) return false;
  const int p10 = exponent - fraction;
  if (m > (uint64_t{1} << 53) || p10 < -22 || p10 > 22) return false;
  double d = static_cast<double>(m);
  d = p10 < 0 ? d / kPow10[-p10] : d * kPow10[p10];
  // 1 <= m <= 2^53 and |p| <= 22 keep d within [1e-22, 9.1e37], inside the
  // normal float range: no underflow, no overflow (or d = 0).
  uint64_t bits;
  std::memcpy(&bits, &d, sizeof bits);
  // The 29 bits below a float's 24-bit significand: exactly half an ulp.
  if ((bits & 0x1fffffffu) == 0x10000000u) return false;
  const float f = static_cast<float>(d);
  *out = negative ? -f : f;
  return true;
}

// Point i's row through the fast fields; false when ParseAsciiRow must
// decide (values stored so far are then stored again or the row throws).
bool ParseAsciiRowFast(const Line& line,
                       const std::vector<FastAsciiField>& fields,
                       size_t i) {
  const char* p = line.b;
  std::string_view token;
  for (const FastAsciiField& f : fields) {
    if (!NextToken(&p, line.e, &token)) return false;
    const char* b = token.data();
    const char* e = b + token.size();
    // ParseNumber's leading '+'.
    if (e - b > 1 && *b == '+' && b[1] != '-' && b[1] != '+') ++b;
    switch (f.kind) {
      case FastAsciiField::kFloat: {
        float v;
        if (!ParseFloatFast(b, e, &v)) {
          const auto r = std::from_chars(b, e, v);
          if (r.ptr != e || r.ec != std::errc()) return false;
        }
        f.floats[f.stride * i] = v;
        break;
      }
      case FastAsciiField::kChannel: {
        uint64_t v;
        if (!ParseCount(std::string_view(b, e - b), 255, &v)) return false;
        f.bytes[3 * i] = static_cast<uint8_t>(v);
        break;
      }
      case FastAsciiField::kPackedRgb: {
        uint64_t v;
        if (!ParseCount(std::string_view(b, e - b), 0xffffffffu, &v))
          return false;
        StorePackedRgb(static_cast<uint32_t>(v), f.bytes + 3 * i);
        break;
      }
    }
  }
  return !NextToken(&p, line.e, &token);
}

// Parses up to `rows` non-blank lines from the reader's position with
// row(line, i), i = 0, 1, ...; returns how many there were (fewer: the data
// ended) and leaves the reader after the last. Large inputs are parsed on
// OpenMP's threads: the bytes are cut into chunks at line ends, a first
// pass counts each chunk's rows and lines, and each chunk then parses its
// rows knowing their indices and line numbers. The rows and the error
// thrown (the first bad row in the file) are those of the serial loop.
template <typename RowFn>
uint64_t ParseAsciiRows(LineReader* reader,
                        const char* end,
                        uint64_t rows,
                        const RowFn& row) {
  const char* begin = reader->position();
  const size_t bytes = static_cast<size_t>(end - begin);
  const int threads = ReaderThreads();
  constexpr size_t kMinChunk = size_t{1} << 20;
  if (threads <= 1 || bytes < 2 * kMinChunk || rows < 1024) {
    Line line;
    uint64_t i = 0;
    for (; i < rows && reader->Next(&line); ++i)
      row(line, static_cast<size_t>(i));
    return i;
  }
  const size_t num_chunks =
      std::min<size_t>(static_cast<size_t>(4 * threads), bytes / kMinChunk);
  std::vector<const char*> cut(num_chunks + 1, end);
  cut[0] = begin;
  for (size_t k = 1; k < num_chunks; ++k) {
    const char* at = std::max(cut[k - 1], begin + bytes / num_chunks * k);
    const void* nl = std::memchr(at, '\n', static_cast<size_t>(end - at));
    cut[k] = nl ? static_cast<const char*>(nl) + 1 : end;
  }
  // Rows (non-blank lines) and lines of each chunk.
  std::vector<uint64_t> chunk_rows(num_chunks), chunk_lines(num_chunks);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (size_t k = 0; k < num_chunks; ++k) {
    LineReader counter(cut[k], cut[k + 1], 0);
    Line line;
    uint64_t n = 0;
    while (counter.Next(&line)) ++n;
    chunk_rows[k] = n;
    chunk_lines[k] = counter.number();
  }
  std::vector<uint64_t> first_row(num_chunks + 1, 0);
  std::vector<uint64_t> lines_before(num_chunks + 1, reader->number());
  for (size_t k = 0; k < num_chunks; ++k) {
    first_row[k + 1] = first_row[k] + chunk_rows[k];
    lines_before[k + 1] = lines_before[k] + chunk_lines[k];
  }
  std::vector<std::exception_ptr> errors(num_chunks);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (size_t k = 0; k < num_chunks; ++k) {
    if (first_row[k] >= rows) continue;
    try {
      LineReader chunk(cut[k], cut[k + 1], lines_before[k]);
      Line line;
      for (uint64_t i = first_row[k]; i < rows && chunk.Next(&line); ++i)
        row(line, static_cast<size_t>(i));
    } catch (...) {
      errors[k] = std::current_exception();
    }
  }
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
  // Leave the reader after row `rows` - 1 (or at the end).
  const uint64_t found = std::min(rows, first_row[num_chunks]);
  size_t k = 0;
  while (k + 1 < num_chunks && first_row[k + 1] < found) ++k;
  LineReader after(cut[k], end, lines_before[k]);
  Line line;
  for (uint64_t i = first_row[k]; i < found; ++i) after.Next(&line);
  *reader = after;
  return found;
}

// ---------------------------------------------------------------------------
// The NaN policy (point_cloud_io.h).

const char* NonFiniteName(float v) {
  return std::isnan(v) ? "nan" : (v > 0 ? "+inf" : "-inf");
}

template <typename T>
void KeepFlagged(const std::vector<uint8_t>& keep, std::vector<T>* v) {
  if (v->empty()) return;
  size_t j = 0;
  for (size_t i = 0; i < keep.size(); ++i) {
    if (keep[i]) (*v)[j++] = (*v)[i];
  }
  v->resize(j);
}

// Throws on the first point with a non-finite coordinate, unless `drop_nan`
// and the point has a NaN coordinate: then it is removed with its attributes.
// Returns the number of points removed.
uint64_t ApplyNanPolicy(const std::string& path,
                        bool drop_nan,
                        PointCloud* cloud) {
  const size_t n = cloud->size();
  const float* xyz = n ? cloud->positions[0].data() : nullptr;
  std::vector<uint8_t> keep;
  uint64_t dropped = 0;
  // The point loop only runs when some coordinate is NaN or infinite.
  const bool any_bad = !cloud->AllPositionsFinite();
  for (size_t i = 0; any_bad && i < n; ++i) {
    const float x = xyz[3 * i], y = xyz[3 * i + 1], z = xyz[3 * i + 2];
    if (std::isfinite(x) && std::isfinite(y) && std::isfinite(z)) continue;
    if (drop_nan && (std::isnan(x) || std::isnan(y) || std::isnan(z))) {
      if (keep.empty()) keep.assign(n, 1);
      keep[i] = 0;
      ++dropped;
      continue;
    }
    const float bad = !std::isfinite(x) ? x : (!std::isfinite(y) ? y : z);
    ThrowInputError(path, "point ", i, " has a non-finite coordinate (",
                    NonFiniteName(bad), ")");
  }
  if (dropped > 0) {
    KeepFlagged(keep, &cloud->positions);
    KeepFlagged(keep, &cloud->colors);
    KeepFlagged(keep, &cloud->confidence);
    KeepFlagged(keep, &cloud->instance_ids);
    KeepFlagged(keep, &cloud->intensity);
    KeepFlagged(keep, &cloud->ring);
    KeepFlagged(keep, &cloud->footprints);
    KeepFlagged(keep, &cloud->footprint_u);
    KeepFlagged(keep, &cloud->footprint_v);
  }
  // Footprints read from a file: finite, >= 0, axes finite (one line naming
  // the file and the point otherwise).
  if (cloud->HasFootprints()) cloud->Check(path);
  return dropped;
}

// ---------------------------------------------------------------------------
// .pcd.bin and KITTI .bin.

// Reads a file of `floats_per_point` little-endian float32 values per point:
// x y z intensity [ring].
PointCloud ReadFloatRecords(const std::string& path,
                            size_t floats_per_point,
                            const char* layout) {
  const FileBuffer file = ReadWholeFile(path);
  const size_t record = floats_per_point * sizeof(float);
  if (file.size % record != 0) {
    ThrowInputError(path, "size ", file.size, " bytes is not a multiple of ",
                    record, " (", layout, ")");
  }
  const size_t n = file.size / record;
  if (n > kMaxPointCloudPoints) {
    ThrowInputError(path, n, " points, more than the limit of ",
                    kMaxPointCloudPoints);
  }
  std::vector<FieldSpec> fields(floats_per_point);
  const Target targets[] = {Target::kX, Target::kY, Target::kZ,
                            Target::kIntensity, Target::kRing};
  std::vector<Column> columns;
  for (size_t k = 0; k < floats_per_point; ++k) {
    fields[k].target = targets[k];
    columns.push_back(Column{file.begin() + 4 * k, record, targets[k],
                             &ConvertColumn<float, false>});
  }
  PointCloud cloud;
  const CloudColumns out = AllocateCloud(n, fields, &cloud);
  ConvertColumns(path, columns, n, out);
  ApplyNanPolicy(path, /*drop_nan=*/false, &cloud);
  return cloud;
}

void WriteFloatRecords(const std::string& path,
                       const PointCloud& cloud,
                       bool with_ring) {
  cloud.Check(path);
  const size_t stride = with_ring ? 5 : 4;
  std::vector<float> values(cloud.size() * stride);
  for (size_t i = 0; i < cloud.size(); ++i) {
    float* v = &values[i * stride];
    v[0] = cloud.positions[i].x();
    v[1] = cloud.positions[i].y();
    v[2] = cloud.positions[i].z();
    v[3] = cloud.HasIntensity() ? cloud.intensity[i] : 0.f;
    if (with_ring) v[4] = cloud.HasRing() ? cloud.ring[i] : 0.f;
  }
  WriteFileAtomic(path, values.data(), values.size() * sizeof(float));
}

// ---------------------------------------------------------------------------
// PLY.

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<FieldSpec> properties;
  bool has_lists = false;
  uint64_t header_line = 0;

  // Bytes of one item without list items (exact when !has_lists).
  uint64_t MinBinaryBytes() const {
    uint64_t bytes = 0;
    for (const FieldSpec& p : properties)
      bytes += SizeOf(p.is_list ? p.list_count_type : p.type);
    return bytes;
  }
};

enum class PlyFormat { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

struct PlyHeader {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
  size_t vertex = 0;       // index of the vertex element
  size_t data_offset = 0;  // first byte after end_header's line
  uint64_t lines = 0;      // header lines (ASCII line numbers continue)
};

bool PlyScalar(std::string_view name, Scalar* type) {
  static const std::pair<const char*, Scalar> kTypes[] = {
      {"char", Scalar::kInt8},      {"int8", Scalar::kInt8},
      {"uchar", Scalar::kUint8},    {"uint8", Scalar::kUint8},
      {"short", Scalar::kInt16},    {"int16", Scalar::kInt16},
      {"ushort", Scalar::kUint16},  {"uint16", Scalar::kUint16},
      {"int", Scalar::kInt32},      {"int32", Scalar::kInt32},
      {"uint", Scalar::kUint32},    {"uint32", Scalar::kUint32},
      {"float", Scalar::kFloat32},  {"float32", Scalar::kFloat32},
      {"double", Scalar::kFloat64}, {"float64", Scalar::kFloat64}};
  for (const auto& [n, t] : kTypes) {
    if (name == n) {
      *type = t;
      return true;
    }
  }
  return false;
}

PlyHeader ParsePlyHeader(const std::string& path, const FileBuffer& file) {
  if (file.size == 0) ThrowInputError(path, "empty file (expected a PLY file)");
  LineReader lines(file.begin(), file.end(), 0);
  Line line;
  lines.NextAny(&line);
  if (line.e > line.b && line.e[-1] == '\r') --line.e;
  if (std::string_view(line.b, static_cast<size_t>(line.e - line.b)) != "ply") {
    ThrowInputError(path, "not a PLY file");
  }
  PlyHeader header;
  bool have_format = false, have_vertex = false;
  auto bad = [&](const std::string& what) {
    ThrowInputError(path, "malformed PLY header: ", what, " (line ",
                    line.number, ")");
  };
  while (true) {
    if (!lines.NextAny(&line)) bad("no end_header");
    const std::vector<std::string_view> t = Tokens(line);
    if (t.empty()) continue;
    const std::string_view key = t[0];
    if (key == "end_header") {
      if (t.size() != 1) bad("text after end_header");
      break;
    }
    if (key == "comment" || key == "obj_info") continue;
    if (key == "format") {
      if (have_format) bad("a second format line");
      if (t.size() != 3) bad("format needs a type and a version");
      if (t[1] == "ascii") {
        header.format = PlyFormat::kAscii;
      } else if (t[1] == "binary_little_endian") {
        header.format = PlyFormat::kBinaryLittleEndian;
      } else if (t[1] == "binary_big_endian") {
        header.format = PlyFormat::kBinaryBigEndian;
      } else {
        bad("unknown format '" + Excerpt(t[1]) + "'");
      }
      have_format = true;
    } else if (key == "element") {
      if (t.size() != 3) bad("element needs a name and a count");
      PlyElement element;
      element.name = std::string(t[1]);
      element.header_line = line.number;
      if (!ParseCount(t[2], uint64_t{1} << 62, &element.count))
        bad("bad element count '" + Excerpt(t[2]) + "'");
      if (element.name == "vertex") {
        if (have_vertex) bad("a second vertex element");
        have_vertex = true;
        header.vertex = header.elements.size();
      }
      header.elements.push_back(std::move(element));
    } else if (key == "property") {
      if (header.elements.empty()) bad("property before any element");
      FieldSpec p;
      if (t.size() == 5 && t[1] == "list") {
        p.is_list = true;
        if (!PlyScalar(t[2], &p.list_count_type) || IsFloat(p.list_count_type))
          bad("bad list length type '" + Excerpt(t[2]) + "'");
        if (!PlyScalar(t[3], &p.type))
          bad("unknown type '" + Excerpt(t[3]) + "'");
        p.type_name = "list " + std::string(t[2]) + " " + std::string(t[3]);
        p.name = std::string(t[4]);
        header.elements.back().has_lists = true;
      } else if (t.size() == 3) {
        if (!PlyScalar(t[1], &p.type))
          bad("unknown type '" + Excerpt(t[1]) + "'");
        p.type_name = std::string(t[1]);
        p.name = std::string(t[2]);
      } else {
        bad("property needs a type and a name");
      }
      header.elements.back().properties.push_back(std::move(p));
    } else {
      bad("unexpected line '" + Excerpt(line.b, line.e) + "'");
    }
  }
  header.lines = line.number;
  header.data_offset = static_cast<size_t>(lines.position() - file.begin());
  if (!have_format)
    ThrowInputError(path, "malformed PLY header: no format line");
  if (!have_vertex) ThrowInputError(path, "no vertex element");
  for (const PlyElement& e : header.elements) {
    if (e.properties.empty() && e.count > 0) {
      ThrowInputError(path, "malformed PLY header: element '", Excerpt(e.name),
                      "' has no properties (line ", e.header_line, ")");
    }
  }
  PlyElement& vertex = header.elements[header.vertex];
  if (vertex.count > kMaxPointCloudPoints) {
    ThrowInputError(path, "header declares ", vertex.count,
                    " vertices, more than the limit of ", kMaxPointCloudPoints);
  }
  AssignTargets(path, "property", &vertex.properties);

  // Every element must fit in what follows the header, before any allocation:
  // binary items need at least their fixed bytes, ASCII items at least one
  // character and one separator per property.
  const uint64_t left = file.size - header.data_offset;
  uint64_t used = 0;
  for (const PlyElement& e : header.elements) {
    const bool ascii = header.format == PlyFormat::kAscii;
    const uint64_t item = ascii ? 2 * e.properties.size() : e.MinBinaryBytes();
    const uint64_t room = ascii ? left + 1 - std::min(used, left + 1)
                                : left - std::min(used, left);
    if (item > 0 && e.count > room / item) {
      ThrowInputError(path, "truncated or corrupt: the header declares ",
                      e.count, " '", Excerpt(e.name), "' items of at least ",
                      item, ascii ? " characters" : " bytes", ", but only ",
                      left, " bytes follow the header");
    }
    used += e.count * item;
  }
  return header;
}

[[noreturn]] void ThrowPlyTruncated(const std::string& path,
                                    const PlyElement& e,
                                    uint64_t item) {
  ThrowInputError(path, "truncated: '", Excerpt(e.name), "' item ", item,
                  " of ", e.count, " runs past the end of the file");
}

// Skips one binary list property of item `i` of `e` at p.
const char* SkipBinaryList(const std::string& path,
                           const PlyElement& e,
                           uint64_t i,
                           const FieldSpec& f,
                           const char* p,
                           const char* end,
                           bool swap) {
  const size_t length_bytes = SizeOf(f.list_count_type);
  if (static_cast<size_t>(end - p) < length_bytes)
    ThrowPlyTruncated(path, e, i);
  const double length = LoadNumber(p, f.list_count_type, swap);
  p += length_bytes;
  if (length < 0) {
    ThrowInputError(path, "'", Excerpt(e.name), "' item ", i,
                    ": negative list length ", length, " for '",
                    Excerpt(f.name), "'");
  }
  if (length >
      static_cast<double>(static_cast<size_t>(end - p) / SizeOf(f.type))) {
    ThrowPlyTruncated(path, e, i);
  }
  return p + static_cast<size_t>(length) * SizeOf(f.type);
}

// Skips the items of a binary element; returns the first byte after them.
const char* SkipBinaryElement(const std::string& path,
                              const PlyElement& e,
                              const char* p,
                              const char* end,
                              bool swap) {
  if (!e.has_lists) {
    const uint64_t item = e.MinBinaryBytes();
    if (item > 0 && e.count > static_cast<uint64_t>(end - p) / item) {
      ThrowPlyTruncated(path, e, static_cast<uint64_t>(end - p) / item);
    }
    return p + e.count * item;
  }
  for (uint64_t i = 0; i < e.count; ++i) {
    for (const FieldSpec& f : e.properties) {
      if (f.is_list) {
        p = SkipBinaryList(path, e, i, f, p, end, swap);
        continue;
      }
      if (static_cast<size_t>(end - p) < SizeOf(f.type))
        ThrowPlyTruncated(path, e, i);
      p += SizeOf(f.type);
    }
  }
  return p;
}

// Reads the binary vertex element starting at p; returns the byte after it.
const char* ReadBinaryVertices(const std::string& path,
                               const PlyElement& vertex,
                               const char* p,
                               const char* end,
                               bool swap,
                               const CloudColumns& out) {
  const size_t n = static_cast<size_t>(vertex.count);
  if (!vertex.has_lists) {
    // Fixed records (checked against the file size): column by column.
    const size_t record = static_cast<size_t>(vertex.MinBinaryBytes());
    if (n > static_cast<size_t>(end - p) / record) {
      ThrowPlyTruncated(path, vertex, static_cast<size_t>(end - p) / record);
    }
    std::vector<Column> columns;
    size_t offset = 0;
    for (const FieldSpec& f : vertex.properties) {
      if (f.target != Target::kSkip) {
        columns.push_back(Column{p + offset, record, f.target,
                                 swap ? ColumnFunctionFor<true>(f.type)
                                      : ColumnFunctionFor<false>(f.type)});
      }
      offset += SizeOf(f.type);
    }
    ConvertColumns(path, columns, n, out);
    return p + n * record;
  }
  // Records with lists: walk each one.
  for (size_t i = 0; i < n; ++i) {
    for (const FieldSpec& f : vertex.properties) {
      if (f.is_list) {
        p = SkipBinaryList(path, vertex, i, f, p, end, swap);
        continue;
      }
      const size_t size = SizeOf(f.type);
      if (static_cast<size_t>(end - p) < size)
        ThrowPlyTruncated(path, vertex, i);
      if (f.target == Target::kPackedRgb) {
        StorePackedRgb(
            swap ? Load<uint32_t, true>(p) : Load<uint32_t, false>(p),
            out.colors + 3 * i);
      } else if (f.target != Target::kSkip) {
        StoreValue(path, f.target, i, LoadNumber(p, f.type, swap), out);
      }
      p += size;
    }
  }
  return p;
}

PointCloud ReadPlyFile(const std::string& path) {
  const FileBuffer file = ReadWholeFile(path);
  PlyHeader header = ParsePlyHeader(path, file);
  const PlyElement& vertex = header.elements[header.vertex];
  PointCloud cloud;
  const CloudColumns out = AllocateCloud(static_cast<size_t>(vertex.count),
                                         vertex.properties, &cloud);
  const char* p = file.begin() + header.data_offset;
  const char* end = file.end();
  if (header.format != PlyFormat::kAscii) {
    const bool swap = header.format == PlyFormat::kBinaryBigEndian;
    for (size_t k = 0; k < header.elements.size(); ++k) {
      if (k == header.vertex) {
        p = ReadBinaryVertices(path, vertex, p, end, swap, out);
      } else {
        p = SkipBinaryElement(path, header.elements[k], p, end, swap);
      }
    }
  } else {
    LineReader lines(p, end, header.lines);
    Line line;
    const std::vector<FastAsciiField> fast =
        FastAsciiFields(vertex.properties, out);
    for (size_t k = 0; k < header.elements.size(); ++k) {
      const PlyElement& e = header.elements[k];
      uint64_t found = 0;
      if (k == header.vertex) {
        found = ParseAsciiRows(
            &lines, end, e.count, [&](const Line& row, size_t i) {
              if (fast.empty() || !ParseAsciiRowFast(row, fast, i))
                ParseAsciiRow(path, row, e.properties, "property", i, out);
            });
      } else {
        while (found < e.count && lines.Next(&line)) ++found;
      }
      if (found < e.count) {
        ThrowInputError(path, "truncated: the file ends after ", found, " of ",
                        e.count, " '", Excerpt(e.name), "' lines");
      }
    }
    if (lines.Next(&line)) {
      ThrowInputError(path, "line ", line.number,
                      ": unexpected data after the last element ('",
                      Excerpt(line.b, line.e), "')");
    }
  }
  ApplyNanPolicy(path, /*drop_nan=*/false, &cloud);
  return cloud;
}

// ---------------------------------------------------------------------------
// PCD.

enum class PcdData { kAscii, kBinary, kBinaryCompressed };

struct PcdHeader {
  std::vector<FieldSpec> fields;
  uint64_t width = 0;
  uint64_t height = 0;
  PcdData data = PcdData::kAscii;
  std::string data_name;
  size_t data_offset = 0;
  uint64_t lines = 0;

  uint64_t points() const { return width * height; }
  size_t PointBytes() const {
    size_t bytes = 0;
    for (const FieldSpec& f : fields) bytes += f.Bytes();
    return bytes;
  }
};

Scalar PcdScalar(char type, uint64_t size) {
  if (type == 'F') return size == 4 ? Scalar::kFloat32 : Scalar::kFloat64;
  const bool is_signed = type == 'I';
  switch (size) {
    case 1:
      return is_signed ? Scalar::kInt8 : Scalar::kUint8;
    case 2:
      return is_signed ? Scalar::kInt16 : Scalar::kUint16;
    case 4:
      return is_signed ? Scalar::kInt32 : Scalar::kUint32;
    default:
      return is_signed ? Scalar::kInt64 : Scalar::kUint64;
  }
}

// The header in [begin, end): the whole file, or whole lines of its start
// that include the DATA line (PcdHeaderEnd); the same lines either way.
PcdHeader ParsePcdHeader(const std::string& path,
                         const char* begin,
                         const char* end) {
  if (begin == end) ThrowInputError(path, "empty file (expected a PCD file)");
  LineReader lines(begin, end, 0);
  Line line;
  auto bad = [&](const std::string& what) {
    ThrowInputError(path, "malformed PCD header: ", what, " (line ",
                    line.number, ")");
  };
  std::vector<std::string_view> names, sizes, types, counts;
  bool have_fields = false, have_size = false, have_type = false,
       have_count = false, have_width = false, have_height = false,
       have_points = false, have_version = false, have_viewpoint = false;
  uint64_t points = 0;
  PcdHeader header;
  bool have_data = false;
  while (!have_data) {
    if (!lines.NextAny(&line)) bad("no DATA line");
    std::vector<std::string_view> t = Tokens(line);
    if (t.empty() || t[0][0] == '#') continue;
    const std::string_view key = t[0];
    std::vector<std::string_view> values(t.begin() + 1, t.end());
    auto once = [&](bool* seen) {
      if (*seen) bad("a second " + std::string(key) + " line");
      *seen = true;
    };
    auto one_count = [&](uint64_t* value) {
      if (values.size() != 1 || !ParseCount(values[0], 0xffffffffu, value))
        bad(std::string(key) + " needs one count");
    };
    if (key == "VERSION") {
      once(&have_version);
      static const char* kVersions[] = {"0.5", "0.6", "0.7", ".5", ".6", ".7"};
      if (values.size() != 1 ||
          std::none_of(std::begin(kVersions), std::end(kVersions),
                       [&](const char* v) { return values[0] == v; })) {
        bad("unsupported VERSION (0.5, 0.6 and 0.7 are read)");
      }
    } else if (key == "FIELDS" || key == "COLUMNS") {
      once(&have_fields);
      names = values;
    } else if (key == "SIZE") {
      once(&have_size);
      sizes = values;
    } else if (key == "TYPE") {
      once(&have_type);
      types = values;
    } else if (key == "COUNT") {
      once(&have_count);
      counts = values;
    } else if (key == "WIDTH") {
      once(&have_width);
      one_count(&header.width);
    } else if (key == "HEIGHT") {
      once(&have_height);
      one_count(&header.height);
    } else if (key == "POINTS") {
      once(&have_points);
      one_count(&points);
    } else if (key == "VIEWPOINT") {
      once(&have_viewpoint);
      bool ok = values.size() == 7;
      for (size_t k = 0; ok && k < values.size(); ++k) {
        double v;
        ok = ParseNumber(values[k], Scalar::kFloat64, &v) == Parse::kOk &&
             std::isfinite(v);
      }
      if (!ok) bad("VIEWPOINT needs 7 finite numbers (tx ty tz qw qx qy qz)");
    } else if (key == "DATA") {
      if (values.size() != 1) bad("DATA needs one format");
      header.data_name = std::string(values[0]);
      if (values[0] == "ascii") {
        header.data = PcdData::kAscii;
      } else if (values[0] == "binary") {
        header.data = PcdData::kBinary;
      } else if (values[0] == "binary_compressed") {
        header.data = PcdData::kBinaryCompressed;
      } else {
        bad("unknown DATA format '" + Excerpt(values[0]) + "'");
      }
      have_data = true;
    } else {
      bad("unexpected line '" + Excerpt(line.b, line.e) + "'");
    }
  }
  header.lines = line.number;
  header.data_offset = static_cast<size_t>(lines.position() - begin);
  if (!have_fields || names.empty()) bad("no FIELDS");
  const size_t nf = names.size();
  if ((have_size && sizes.size() != nf) || (have_type && types.size() != nf) ||
      (have_count && counts.size() != nf)) {
    bad("FIELDS, SIZE, TYPE and COUNT have different lengths");
  }
  for (size_t k = 0; k < nf; ++k) {
    FieldSpec f;
    f.name = std::string(names[k]);
    uint64_t size = 4;
    if (have_size && (!ParseCount(sizes[k], 8, &size) ||
                      (size != 1 && size != 2 && size != 4 && size != 8))) {
      bad("SIZE '" + Excerpt(sizes[k]) + "' of field '" + Excerpt(f.name) +
          "' (1, 2, 4 or 8)");
    }
    char type = 'F';
    if (have_type) {
      if (types[k] != "I" && types[k] != "U" && types[k] != "F")
        bad("TYPE '" + Excerpt(types[k]) + "' (I, U or F)");
      type = types[k][0];
    }
    if (type == 'F' && size != 4 && size != 8)
      bad("field '" + Excerpt(f.name) + "' is a float of " +
          std::to_string(size) + " bytes");
    if (have_count &&
        (!ParseCount(counts[k], uint64_t{1} << 20, &f.count) || f.count == 0)) {
      bad("COUNT '" + Excerpt(counts[k]) + "' (1 to 1048576)");
    }
    f.type = PcdScalar(type, size);
    f.type_name = std::string(1, type) + " " + std::to_string(size);
    header.fields.push_back(std::move(f));
  }
  if (!have_width && !have_height) {
    if (!have_points) bad("no WIDTH, HEIGHT or POINTS");
    header.width = points;
    header.height = 1;
  } else if (!have_width) {
    bad("HEIGHT without WIDTH");
  } else if (!have_height) {
    header.height = 1;
  }
  if (have_points && points != header.points()) {
    bad("POINTS " + std::to_string(points) + " is not WIDTH x HEIGHT (" +
        std::to_string(header.width) + " x " + std::to_string(header.height) +
        ")");
  }
  if (header.points() > kMaxPointCloudPoints) {
    ThrowInputError(path, "header declares ", header.points(),
                    " points, more than the limit of ", kMaxPointCloudPoints);
  }
  AssignTargets(path, "field", &header.fields);
  return header;
}

// The end of the whole lines in head[0, n) when one of them is a DATA line
// (its first token is DATA); nullptr otherwise.
const char* PcdHeaderEnd(const char* head, size_t n) {
  const void* last = n > 0 ? memrchr(head, '\n', n) : nullptr;
  if (!last) return nullptr;
  const char* end = static_cast<const char*>(last) + 1;
  LineReader lines(head, end, 0);
  Line line;
  while (lines.Next(&line)) {
    const size_t len = static_cast<size_t>(line.e - line.b);
    if (len >= 4 && std::memcmp(line.b, "DATA", 4) == 0 &&
        (len == 4 || IsBlank(line.b[4]))) {
      return end;
    }
  }
  return nullptr;
}

// The LZF sink of a binary_compressed block (PCL's layout: the fields one
// after another, all of field 0's values, then field 1's, ...): each piece
// of the stream is converted into the cloud's columns as it comes, whole
// values only, so no decompressed copy of the points is ever held.
class CompressedColumnsSink {
 public:
  CompressedColumnsSink(const std::string& path,
                        const PcdHeader& header,
                        const CloudColumns& out)
      : path_(path), out_(out), n_(header.points()) {
    uint64_t begin = 0;
    for (const FieldSpec& f : header.fields) {
      fields_.push_back(
          Field{begin, f.Bytes(), f.target, ColumnFunctionFor<false>(f.type)});
      begin += n_ * f.Bytes();
    }
  }

  // Converts the whole values in [offset, offset + n) of the stream; returns
  // the bytes used (a value cut by the piece's end waits for the next one).
  size_t Consume(uint64_t offset, const uint8_t* data, size_t n) {
    const uint64_t end = offset + n;
    uint64_t used = offset;
    for (const Field& f : fields_) {
      const uint64_t field_end = f.begin + n_ * f.bytes;
      if (field_end <= offset || f.begin >= end) continue;
      const uint64_t a = std::max(offset, f.begin);  // a value's start
      const uint64_t first = (a - f.begin) / f.bytes;
      const uint64_t last = (std::min(end, field_end) - f.begin) / f.bytes;
      if (f.target != Target::kSkip && last > first) {
        f.convert(path_, reinterpret_cast<const char*>(data + (a - offset)),
                  f.bytes, static_cast<size_t>(first),
                  static_cast<size_t>(last - first), f.target, out_);
      }
      used = f.begin + last * f.bytes;
    }
    return static_cast<size_t>(used - offset);
  }

 private:
  struct Field {
    uint64_t begin;  // stream offset of the field's first value
    size_t bytes;    // bytes a point
    Target target;
    ColumnFn convert;
  };
  const std::string& path_;
  const CloudColumns& out_;
  const uint64_t n_;
  std::vector<Field> fields_;
};

// Decodes the LZF block of compressed_size bytes that `file` reads next.
void DecodeCompressedPoints(const std::string& path,
                            const PcdHeader& header,
                            FileReader* file,
                            uint32_t compressed_size,
                            const CloudColumns& out) {
  // 256 KiB pieces and input chunks: both stay in a core's L2 cache.
  constexpr size_t kPieceBytes = size_t{256} << 10;
  const uint64_t uncompressed = header.points() * header.PointBytes();
  CompressedColumnsSink sink(path, header, out);
  uint64_t produced = 0;
  const lzf_stream::LzfResult result = lzf_stream::DecodeLzfStream(
      compressed_size, uncompressed, kPieceBytes, kPieceBytes, sink, &produced,
      [&](uint8_t* dst, size_t n) { return file->ReadNext(dst, n); });
  if (result == lzf_stream::LzfResult::kInputStopped) file->ThrowReadError();
  if (result != lzf_stream::LzfResult::kOk) {
    // Bytes decoded before the failure (short: all the stream gave).
    ThrowInputError(
        path, "corrupt LZF data (",
        result == lzf_stream::LzfResult::kShort ? "short" : "invalid",
        " stream: ", produced, " of ", uncompressed, " bytes)");
  }
}

PointCloud ReadPcdFile(const std::string& path, PcdReadSummary* summary) {
  // The header from the file's first 64 KiB (whole lines), or from all of it
  // when it is longer. ASCII points are read whole; binary points and an LZF
  // block are converted (decoded) chunk by chunk as they are read, never held
  // whole.
  FileReader file(path, size_t{64} << 10);
  const char* header_end = PcdHeaderEnd(file.begin(), file.buffered());
  if (!header_end) {
    file.ReadAll();
    header_end = file.begin() + file.size();
  }
  const PcdHeader header = ParsePcdHeader(path, file.begin(), header_end);
  if (header.data == PcdData::kAscii) {
    file.ReadAll();
  } else if (header.data == PcdData::kBinaryCompressed) {
    file.Buffer(std::min<uint64_t>(file.size(), header.data_offset + 8));
  }
  const size_t n = static_cast<size_t>(header.points());
  const size_t point_bytes = header.PointBytes();
  const char* data = file.begin() + header.data_offset;
  const uint64_t left = file.size() - header.data_offset;
  PointCloud cloud;
  uint32_t compressed_size = 0;  // binary_compressed: the LZF block's bytes

  // Sizes first, allocation after.
  if (header.data == PcdData::kAscii) {
    uint64_t values = 0;
    for (const FieldSpec& f : header.fields) values += f.count;
    if (n > 0 && n > (left + 1) / (2 * values)) {
      ThrowInputError(path, "truncated or corrupt: the header declares ", n,
                      " points of ", values, " values, but only ", left,
                      " bytes follow the header");
    }
  } else if (header.data == PcdData::kBinary) {
    if (n > 0 && n > left / point_bytes) {
      ThrowInputError(path, "truncated or corrupt: the header declares ", n,
                      " points of ", point_bytes, " bytes (", n * point_bytes,
                      " bytes), but only ", left, " bytes follow the header");
    }
  } else if (n > 0) {
    // PCL's layout: uint32 compressed size, uint32 uncompressed size, LZF
    // data of the fields one after another (all x, then all y, ...).
    if (left < 8) {
      ThrowInputError(path,
                      "truncated: the compressed block's sizes are "
                      "missing");
    }
    uint32_t compressed = 0, uncompressed = 0;
    std::memcpy(&compressed, data, 4);
    std::memcpy(&uncompressed, data + 4, 4);
    const uint64_t need = uint64_t{n} * point_bytes;
    if (uncompressed != need) {
      ThrowInputError(path, "corrupt: the compressed block declares ",
                      uncompressed, " bytes of points, the header needs ", n,
                      " x ", point_bytes, " = ", need);
    }
    if (compressed > left - 8) {
      ThrowInputError(path, "truncated: the compressed block declares ",
                      compressed, " bytes, only ", left - 8,
                      " bytes follow it");
    }
    // LZF expands at most 88x (3 bytes of back-reference copy 264).
    if (compressed == 0 || uncompressed / 88 > compressed) {
      ThrowInputError(path, "corrupt: ", compressed,
                      " bytes of LZF data cannot hold ", uncompressed,
                      " bytes");
    }
    compressed_size = compressed;
  }

  const CloudColumns out = AllocateCloud(n, header.fields, &cloud);
  if (header.data == PcdData::kAscii) {
    const char* file_end = file.begin() + file.size();
    LineReader lines(data, file_end, header.lines);
    Line line;
    const std::vector<FastAsciiField> fast =
        FastAsciiFields(header.fields, out);
    const uint64_t found =
        ParseAsciiRows(&lines, file_end, n, [&](const Line& row, size_t i) {
          if (fast.empty() || !ParseAsciiRowFast(row, fast, i))
            ParseAsciiRow(path, row, header.fields, "field", i, out);
        });
    if (found < n) {
      ThrowInputError(path, "truncated: the file ends after ", found, " of ", n,
                      " points");
    }
    if (lines.Next(&line)) {
      ThrowInputError(path, "line ", line.number,
                      ": unexpected data after the last point ('",
                      Excerpt(line.b, line.e), "')");
    }
  } else if (header.data == PcdData::kBinary && n > 0) {
    // Read on from the header in chunks of about 256 KiB of whole points,
    // each converted while it is in cache; the file is never held whole.
    const size_t chunk_points =
        std::max<size_t>(1, (size_t{256} << 10) / point_bytes);
    std::unique_ptr<char[]> chunk(
        new char[std::min(chunk_points, n) * point_bytes]);
    std::vector<Column> columns;
    size_t offset = 0;
    for (const FieldSpec& f : header.fields) {
      if (f.target != Target::kSkip) {
        columns.push_back(Column{chunk.get() + offset, point_bytes, f.target,
                                 ColumnFunctionFor<false>(f.type)});
      }
      offset += f.Bytes();
    }
    file.Seek(header.data_offset);
    for (size_t first = 0; first < n; first += chunk_points) {
      const size_t m = std::min(chunk_points, n - first);
      if (!file.ReadNext(reinterpret_cast<uint8_t*>(chunk.get()),
                         m * point_bytes)) {
        file.ThrowReadError();
      }
      ConvertColumns(path, columns, m, out, first);
    }
  } else if (n > 0) {
    file.Seek(header.data_offset + 8);
    DecodeCompressedPoints(path, header, &file, compressed_size, out);
  }
  const uint64_t dropped =
      ApplyNanPolicy(path, /*drop_nan=*/header.height > 1, &cloud);
  if (summary) {
    summary->width = header.width;
    summary->height = header.height;
    summary->data = header.data_name;
    summary->dropped_nan_points = dropped;
  }
  return cloud;
}

// ---------------------------------------------------------------------------
// Writers.

// %.9g (round-trips float32), as the writers have always written floats.
inline void AppendFloat(float v, std::string* out) {
  char buf[32];
  const auto r =
      std::to_chars(buf, buf + sizeof(buf), v, std::chars_format::general, 9);
  out->append(buf, r.ptr);
}

template <typename Int>
inline void AppendInt(Int v, std::string* out) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  out->append(buf, r.ptr);
}

uint32_t PackRgb(const Color3u8& c) {
  return (uint32_t{c[0]} << 16) | (uint32_t{c[1]} << 8) | uint32_t{c[2]};
}

// The fields both writers emit, in order.
struct OutField {
  enum Kind {
    kXyz,
    kColor,
    kConfidence,
    kInstanceId,
    kIntensity,
    kRing,
    kFootprint,
    kFootprintAxes
  };
  Kind kind;
  size_t bytes;
};

// PLY: colour as 3 uchar, then confidence, instance_id, intensity, ring. PCD
// (the order of the PCL-based writer before): colour packed in a uint32, then
// intensity, confidence, instance_id, ring. Both then footprint and the six
// footprint axis values (u then v, x y z each) when the cloud has them.
std::vector<OutField> OutFields(const PointCloud& cloud, bool pcd) {
  std::vector<OutField> fields = {{OutField::kXyz, 12}};
  if (cloud.HasColors()) fields.push_back({OutField::kColor, pcd ? 4u : 3u});
  if (pcd && cloud.HasIntensity()) fields.push_back({OutField::kIntensity, 4});
  if (cloud.HasConfidence()) fields.push_back({OutField::kConfidence, 4});
  if (cloud.HasInstanceIds()) fields.push_back({OutField::kInstanceId, 4});
  if (!pcd && cloud.HasIntensity()) fields.push_back({OutField::kIntensity, 4});
  if (cloud.HasRing()) fields.push_back({OutField::kRing, 4});
  if (cloud.HasFootprints()) fields.push_back({OutField::kFootprint, 4});
  if (!cloud.footprint_u.empty())
    fields.push_back({OutField::kFootprintAxes, 24});
  return fields;
}

// Point-major binary records of OutFields(cloud, pcd).
void AppendBinaryRecords(const PointCloud& cloud, bool pcd, std::string* out) {
  const std::vector<OutField> fields = OutFields(cloud, pcd);
  size_t record = 0;
  for (const OutField& f : fields) record += f.bytes;
  const size_t start = out->size();
  out->resize(start + record * cloud.size());
  char* p = out->data() + start;
  for (size_t i = 0; i < cloud.size(); ++i) {
    for (const OutField& f : fields) {
      switch (f.kind) {
        case OutField::kXyz:
          std::memcpy(p, cloud.positions[i].data(), 12);
          break;
        case OutField::kColor:
          if (pcd) {
            const uint32_t rgb = PackRgb(cloud.colors[i]);
            std::memcpy(p, &rgb, 4);
          } else {
            std::memcpy(p, cloud.colors[i].data(), 3);
          }
          break;
        case OutField::kConfidence:
          std::memcpy(p, &cloud.confidence[i], 4);
          break;
        case OutField::kInstanceId:
          std::memcpy(p, &cloud.instance_ids[i], 4);
          break;
        case OutField::kIntensity:
          std::memcpy(p, &cloud.intensity[i], 4);
          break;
        case OutField::kRing:
          std::memcpy(p, &cloud.ring[i], 4);
          break;
        case OutField::kFootprint:
          std::memcpy(p, &cloud.footprints[i], 4);
          break;
        case OutField::kFootprintAxes:
          std::memcpy(p, cloud.footprint_u[i].data(), 12);
          std::memcpy(p + 12, cloud.footprint_v[i].data(), 12);
          break;
      }
      p += f.bytes;
    }
  }
}

// One ASCII line per point of OutFields(cloud, pcd), values separated by one
// space.
void AppendAsciiRecords(const PointCloud& cloud, bool pcd, std::string* out) {
  const std::vector<OutField> fields = OutFields(cloud, pcd);
  for (size_t i = 0; i < cloud.size(); ++i) {
    for (const OutField& f : fields) {
      switch (f.kind) {
        case OutField::kXyz:
          AppendFloat(cloud.positions[i].x(), out);
          *out += ' ';
          AppendFloat(cloud.positions[i].y(), out);
          *out += ' ';
          AppendFloat(cloud.positions[i].z(), out);
          break;
        case OutField::kColor:
          if (pcd) {
            *out += ' ';
            AppendInt(PackRgb(cloud.colors[i]), out);
          } else {
            for (int k = 0; k < 3; ++k) {
              *out += ' ';
              AppendInt(int{cloud.colors[i][k]}, out);
            }
          }
          break;
        case OutField::kConfidence:
          *out += ' ';
          AppendFloat(cloud.confidence[i], out);
          break;
        case OutField::kInstanceId:
          *out += ' ';
          AppendInt(cloud.instance_ids[i], out);
          break;
        case OutField::kIntensity:
          *out += ' ';
          AppendFloat(cloud.intensity[i], out);
          break;
        case OutField::kRing:
          *out += ' ';
          AppendFloat(cloud.ring[i], out);
          break;
        case OutField::kFootprint:
          *out += ' ';
          AppendFloat(cloud.footprints[i], out);
          break;
        case OutField::kFootprintAxes:
          for (const Eigen::Vector3f* axis :
               {&cloud.footprint_u[i], &cloud.footprint_v[i]}) {
            for (int k = 0; k < 3; ++k) {
              *out += ' ';
              AppendFloat((*axis)[k], out);
            }
          }
          break;
      }
    }
    *out += '\n';
  }
}

}  // namespace

PointCloud ReadNuscenesLidarBin(const std::string& path) {
  return ReadFloatRecords(path, 5,
                          "float32 x 5 per point: x y z intensity ring");
}

void WriteNuscenesLidarBin(const std::string& path, const PointCloud& cloud) {
  WriteFloatRecords(path, cloud, /*with_ring=*/true);
}

PointCloud ReadKittiVelodyneBin(const std::string& path) {
  return ReadFloatRecords(path, 4, "float32 x 4 per point: x y z reflectance");
}

void WriteKittiVelodyneBin(const std::string& path, const PointCloud& cloud) {
  WriteFloatRecords(path, cloud, /*with_ring=*/false);
}

PointCloud ReadPly(const std::string& path) { return ReadPlyFile(path); }

void WritePly(const std::string& path, const PointCloud& cloud, bool binary) {
  cloud.Check(path);
  std::string out = "ply\n";
  out += binary ? "format binary_little_endian 1.0\n" : "format ascii 1.0\n";
  out += "comment written by geodrive\n";
  out += "element vertex " + std::to_string(cloud.size()) + "\n";
  out += "property float x\nproperty float y\nproperty float z\n";
  if (cloud.HasColors())
    out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (cloud.HasConfidence()) out += "property float confidence\n";
  if (cloud.HasInstanceIds()) out += "property int instance_id\n";
  if (cloud.HasIntensity()) out += "property float intensity\n";
  if (cloud.HasRing()) out += "property float ring\n";
  if (cloud.HasFootprints()) out += "property float footprint\n";
  if (!cloud.footprint_u.empty()) {
    for (const char* name : kFootprintAxisNames)
      out += std::string("property float ") + name + "\n";
  }
  out += "end_header\n";
  if (binary) {
    AppendBinaryRecords(cloud, /*pcd=*/false, &out);
  } else {
    AppendAsciiRecords(cloud, /*pcd=*/false, &out);
  }
  WriteFileAtomic(path, out);
}

PointCloud ReadPcd(const std::string& path) {
  return ReadPcdFile(path, nullptr);
}

PointCloud ReadPcd(const std::string& path, PcdReadSummary* summary) {
  return ReadPcdFile(path, summary);
}

void WritePcd(const std::string& path, const PointCloud& cloud, bool binary) {
  cloud.Check(path);
  std::string fields = "x y z", sizes = "4 4 4", types = "F F F",
              counts = "1 1 1";
  auto add = [&](const char* name, const char* type) {
    fields += std::string(" ") + name;
    sizes += " 4";
    types += std::string(" ") + type;
    counts += " 1";
  };
  // PCL 1.13 declares rgb as F in binary files and, as it writes the uint32
  // as an integer there, as U in ASCII ones.
  if (cloud.HasColors()) add("rgb", binary && !cloud.empty() ? "F" : "U");
  if (cloud.HasIntensity()) add("intensity", "F");
  if (cloud.HasConfidence()) add("confidence", "F");
  if (cloud.HasInstanceIds()) add("instance_id", "I");
  if (cloud.HasRing()) add("ring", "F");
  if (cloud.HasFootprints()) add("footprint", "F");
  if (!cloud.footprint_u.empty()) {
    for (const char* name : kFootprintAxisNames) add(name, "F");
  }
  const std::string n = std::to_string(cloud.size());
  // An empty cloud is written as ASCII, as PCL does not write empty binary
  // files.
  binary = binary && !cloud.empty();
  std::string out = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n";
  out += "FIELDS " + fields + "\nSIZE " + sizes + "\nTYPE " + types +
         "\nCOUNT " + counts + "\nWIDTH " + n +
         "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + n + "\n";
  out += binary ? "DATA binary\n" : "DATA ascii\n";
  if (binary) {
    AppendBinaryRecords(cloud, /*pcd=*/true, &out);
  } else {
    AppendAsciiRecords(cloud, /*pcd=*/true, &out);
  }
  WriteFileAtomic(path, out);
}

PointCloud ReadPointCloud(const std::string& path) {
  const std::string name = LowerFileName(path);
  if (EndsWith(name, ".ply")) return ReadPly(path);
  if (EndsWith(name, ".pcd")) return ReadPcd(path);
  if (EndsWith(name, ".pcd.bin")) return ReadNuscenesLidarBin(path);
  if (EndsWith(name, ".bin")) return ReadKittiVelodyneBin(path);
  ThrowInputError(
      path,
      "unknown point cloud format (expected .ply, .pcd, .pcd.bin or .bin)");
}

void WritePointCloud(const std::string& path, const PointCloud& cloud) {
  const std::string name = LowerFileName(path);
  if (EndsWith(name, ".ply")) return WritePly(path, cloud);
  if (EndsWith(name, ".pcd")) return WritePcd(path, cloud);
  if (EndsWith(name, ".pcd.bin")) return WriteNuscenesLidarBin(path, cloud);
  if (EndsWith(name, ".bin")) return WriteKittiVelodyneBin(path, cloud);
  ThrowInputError(
      path,
      "unknown point cloud format (expected .ply, .pcd, .pcd.bin or .bin)");
}

}  // namespace geodrive
