#include "geometry/npy.h"

#include <Eigen/Core>
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <sstream>

#include "geometry/util/files.h"
#include "geometry/util/input_file.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

constexpr char kMagic[] = "\x93NUMPY";
constexpr size_t kMagicLen = 6;
constexpr size_t kArrayAlign =
    64;  // numpy's ARRAY_ALIGN: data starts at a multiple of this
constexpr size_t kMaxHeaderLen =
    1u << 20;                 // sanity limit for the header dict (numpy: 10000)
constexpr int kMaxDims = 32;  // numpy's NPY_MAXDIMS
constexpr int kGrowthAxisMaxDigits =
    21;  // numpy >= 1.23 pads the header for in-place growth

static_assert(sizeof(float) == 4 && sizeof(double) == 8,
              "IEEE float sizes expected");

bool HostIsLittleEndian() {
  const uint16_t probe = 1;
  uint8_t first;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

// Printable one-line excerpt of a header for error messages.
std::string Excerpt(const std::string& text, size_t max_len = 100) {
  std::string out;
  for (char c : text.substr(0, max_len)) {
    out += std::isprint(static_cast<unsigned char>(c)) ? c : '?';
  }
  while (!out.empty() && out.back() == ' ') out.pop_back();
  if (text.size() > max_len) out += "...";
  return out;
}

// Parses the descr string ("<f4", ">i8", "|b1", ...).
bool ParseDescr(const std::string& descr, NpyDtype* dtype, bool* big_endian) {
  std::string code = descr;
  char order = '=';
  if (!code.empty() &&
      (code[0] == '<' || code[0] == '>' || code[0] == '|' || code[0] == '=')) {
    order = code[0];
    code = code.substr(1);
  }
  if (code == "f4")
    *dtype = NpyDtype::kFloat32;
  else if (code == "f8")
    *dtype = NpyDtype::kFloat64;
  else if (code == "u1")
    *dtype = NpyDtype::kUint8;
  else if (code == "b1")
    *dtype = NpyDtype::kBool;
  else if (code == "i4")
    *dtype = NpyDtype::kInt32;
  else if (code == "i8")
    *dtype = NpyDtype::kInt64;
  else if (code == "u2")
    *dtype = NpyDtype::kUint16;
  else if (code == "f2")
    *dtype = NpyDtype::kFloat16;
  else
    return false;
  // '|' (not applicable) and '=' (native) both mean the host order,
  // little-endian here.
  *big_endian = order == '>' && NpyDtypeSize(*dtype) > 1;
  return true;
}

// Recursive-descent parser for the header dict, a Python literal such as
//   {'descr': '<f4', 'fortran_order': False, 'shape': (288, 512), }
class HeaderDictParser {
 public:
  HeaderDictParser(const std::string& path, const std::string& text)
      : path_(path), text_(text) {}

  void Parse(NpyHeader* header) {
    bool have_descr = false, have_order = false, have_shape = false;
    SkipSpace();
    Expect('{');
    while (true) {
      SkipSpace();
      if (Peek() == '}') break;
      const std::string key = ParseString();
      SkipSpace();
      Expect(':');
      SkipSpace();
      if (key == "descr") {
        if (have_descr) Fail("duplicate key 'descr'");
        have_descr = true;
        if (Peek() == '[' || Peek() == '{') {
          ThrowInputError(
              path_, "unsupported dtype (structured arrays are not supported; ",
              "supported: <f4 <f8 |u1 |b1 <i4 <i8 <u2, either byte order)");
        }
        const std::string descr = ParseString();
        if (!ParseDescr(descr, &header->dtype, &header->big_endian)) {
          ThrowInputError(
              path_, "unsupported dtype '", Excerpt(descr, 20),
              "' (supported: <f4 <f8 |u1 |b1 <i4 <i8 <u2, either byte order)");
        }
      } else if (key == "fortran_order") {
        if (have_order) Fail("duplicate key 'fortran_order'");
        have_order = true;
        header->fortran_order = ParseBool();
      } else if (key == "shape") {
        if (have_shape) Fail("duplicate key 'shape'");
        have_shape = true;
        header->shape = ParseShape();
      } else {
        Fail("unexpected key '" + Excerpt(key, 30) + "'");
      }
      SkipSpace();
      if (Peek() == ',') {
        ++pos_;
        continue;
      }
      SkipSpace();
      if (Peek() != '}') Fail("expected ',' or '}'");
    }
    ++pos_;  // '}'
    SkipSpace();
    if (pos_ != text_.size()) Fail("unexpected text after '}'");
    if (!have_descr) Fail("missing key 'descr'");
    if (!have_order) Fail("missing key 'fortran_order'");
    if (!have_shape) Fail("missing key 'shape'");
  }

 private:
  [[noreturn]] void Fail(const std::string& what) const {
    ThrowInputError(path_, "bad header dict: ", what, " at offset ", pos_,
                    " in \"", Excerpt(text_), "\"");
  }
  char Peek() const { return pos_ < text_.size() ? text_[pos_] : '\0'; }
  void SkipSpace() {
    while (pos_ < text_.size() &&
           std::isspace(static_cast<unsigned char>(text_[pos_])))
      ++pos_;
  }
  void Expect(char c) {
    if (Peek() != c) Fail(std::string("expected '") + c + "'");
    ++pos_;
  }
  std::string ParseString() {
    const char quote = Peek();
    if (quote != '\'' && quote != '"') Fail("expected a quoted string");
    const size_t end = text_.find(quote, pos_ + 1);
    if (end == std::string::npos) Fail("unterminated string");
    std::string s = text_.substr(pos_ + 1, end - pos_ - 1);
    if (s.find('\\') != std::string::npos)
      Fail("escape sequences are not supported");
    pos_ = end + 1;
    return s;
  }
  bool ParseBool() {
    if (text_.compare(pos_, 4, "True") == 0) {
      pos_ += 4;
      return true;
    }
    if (text_.compare(pos_, 5, "False") == 0) {
      pos_ += 5;
      return false;
    }
    Fail("expected True or False");
  }
  std::vector<int64_t> ParseShape() {
    std::vector<int64_t> shape;
    Expect('(');
    SkipSpace();
    bool need_comma_for_one = true;
    while (Peek() != ')') {
      if (!std::isdigit(static_cast<unsigned char>(Peek()))) {
        Fail(Peek() == '-' ? "negative dimension in shape"
                           : "expected a dimension in shape");
      }
      int64_t dim = 0;
      while (std::isdigit(static_cast<unsigned char>(Peek()))) {
        const int digit = Peek() - '0';
        if (dim > (std::numeric_limits<int64_t>::max() - digit) / 10) {
          ThrowInputError(
              path_,
              "shape overflows: a dimension does not fit in 64 bits in \"",
              Excerpt(text_), "\"");
        }
        dim = dim * 10 + digit;
        ++pos_;
      }
      if (Peek() == 'L') ++pos_;  // Python 2 long suffix
      shape.push_back(dim);
      if (shape.size() > static_cast<size_t>(kMaxDims)) {
        Fail("more than 32 dimensions (numpy's limit)");
      }
      SkipSpace();
      if (Peek() == ',') {
        ++pos_;
        SkipSpace();
        need_comma_for_one = false;
      } else if (Peek() != ')') {
        Fail("expected ',' or ')' in shape");
      } else if (shape.size() == 1 && need_comma_for_one) {
        Fail("'(n)' is not a tuple: a 1-d shape is written '(n,)'");
      }
    }
    ++pos_;
    return shape;
  }

  const std::string& path_;
  const std::string& text_;
  size_t pos_ = 0;
};

// Checked element count and byte size of a shape; throws on overflow.
// The element count of `shape`: 0 if any axis is 0 (then the other axes may
// be anything a header allows, their product beyond int64), else the product,
// which the readers have checked (CheckedByteSize); an overflow here is a
// bug, reported as an error rather than wrapped.
int64_t ShapeElements(const std::vector<int64_t>& shape) {
  for (int64_t d : shape) {
    if (d == 0) return 0;
  }
  int64_t n = 1;
  for (int64_t d : shape) {
    if (__builtin_mul_overflow(n, d, &n)) {
      throw InputError("npy array: shape has more than 2^63 elements");
    }
  }
  return n;
}

uint64_t CheckedByteSize(const std::string& path,
                         const std::vector<int64_t>& shape,
                         NpyDtype dtype) {
  uint64_t count = 1;
  bool zero = false;
  for (int64_t d : shape) zero = zero || d == 0;
  const uint64_t limit =
      static_cast<uint64_t>(std::numeric_limits<int64_t>::max());
  for (int64_t d : shape) {
    if (zero) break;
    const uint64_t ud = static_cast<uint64_t>(d);
    if (count > limit / ud) {
      std::ostringstream os;
      for (size_t i = 0; i < shape.size(); ++i)
        os << (i ? ", " : "") << shape[i];
      ThrowInputError(path, "shape overflows: (", os.str(),
                      ") has more than 2^63 elements");
    }
    count *= ud;
  }
  if (zero) return 0;
  const uint64_t elem = NpyDtypeSize(dtype);
  if (count > limit / elem) {
    ThrowInputError(path, "size overflows: ", count, " elements of ", elem,
                    " bytes do not fit in 2^63 bytes");
  }
  return count * elem;
}

NpyHeader ParseHeaderBytes(const std::string& path,
                           const uint8_t* data,
                           size_t available,
                           uint64_t file_size) {
  if (available < kMagicLen || std::memcmp(data, kMagic, kMagicLen) != 0) {
    ThrowInputError(
        path, "not a .npy file (bad magic: expected \\x93NUMPY, file has ",
        file_size, " bytes)");
  }
  if (available < 10)
    ThrowInputError(path, "truncated: file ends inside the .npy preamble");
  NpyHeader header;
  header.major_version = data[6];
  header.minor_version = data[7];
  if (!((header.major_version >= 1 && header.major_version <= 3) &&
        header.minor_version == 0)) {
    ThrowInputError(path, "unsupported .npy format version ",
                    header.major_version, ".", header.minor_version,
                    " (supported: 1.0, 2.0, 3.0)");
  }
  size_t prefix = 10;
  uint64_t header_len = data[8] | (uint64_t{data[9]} << 8);
  if (header.major_version >= 2) {
    prefix = 12;
    if (available < 12)
      ThrowInputError(path, "truncated: file ends inside the .npy preamble");
    header_len |= (uint64_t{data[10]} << 16) | (uint64_t{data[11]} << 24);
  }
  if (header_len > kMaxHeaderLen) {
    ThrowInputError(path, "bad header: header length ", header_len,
                    " exceeds the limit of ", kMaxHeaderLen, " bytes");
  }
  if (prefix + header_len > available) {
    ThrowInputError(path, "truncated: header says ", header_len,
                    " bytes of header, file has ", file_size - prefix);
  }
  const std::string text(reinterpret_cast<const char*>(data + prefix),
                         header_len);
  HeaderDictParser(path, text).Parse(&header);
  header.data_offset = prefix + header_len;
  CheckedByteSize(path, header.shape, header.dtype);
  return header;
}

// Reads the preamble and header of an open file.
NpyHeader ReadHeader(const std::string& path,
                     std::FILE* file,
                     uint64_t file_size) {
  std::vector<uint8_t> buffer(12);
  const size_t got = std::fread(buffer.data(), 1, buffer.size(), file);
  buffer.resize(got);
  if (got >= 12 && std::memcmp(buffer.data(), kMagic, kMagicLen) == 0) {
    uint64_t header_len = buffer[8] | (uint64_t{buffer[9]} << 8);
    if (buffer[6] >= 2)
      header_len |= (uint64_t{buffer[10]} << 16) | (uint64_t{buffer[11]} << 24);
    const uint64_t want = std::min<uint64_t>(
        12 + header_len, std::min<uint64_t>(file_size, kMaxHeaderLen + 12));
    if (want > got) {
      buffer.resize(want);
      buffer.resize(got + std::fread(buffer.data() + got, 1, want - got, file));
    }
  }
  return ParseHeaderBytes(path, buffer.data(), buffer.size(), file_size);
}

struct FileCloser {
  void operator()(std::FILE* f) const {
    if (f) std::fclose(f);
  }
};

void SwapBytes(uint8_t* data, size_t count, size_t elem) {
  if (elem == 1) return;
  for (size_t i = 0; i < count; ++i)
    std::reverse(data + i * elem, data + (i + 1) * elem);
}

// Copies between C order and Fortran order. With fortran_to_c, `src` is
// Fortran-ordered and `dst` C-ordered; otherwise the reverse.
void Reorder(const uint8_t* src,
             uint8_t* dst,
             const std::vector<int64_t>& shape,
             size_t elem,
             bool fortran_to_c) {
  const size_t ndim = shape.size();
  const int64_t count = ShapeElements(shape);
  if (count == 0) return;
  // Fortran strides (in elements) of each axis.
  std::vector<int64_t> fstride(ndim, 1);
  for (size_t k = 1; k < ndim; ++k) fstride[k] = fstride[k - 1] * shape[k - 1];
  std::vector<int64_t> index(ndim, 0);
  int64_t foffset = 0;
  for (int64_t c = 0; c < count; ++c) {
    if (fortran_to_c) {
      std::memcpy(dst + c * elem, src + foffset * elem, elem);
    } else {
      std::memcpy(dst + foffset * elem, src + c * elem, elem);
    }
    // Advance the C-order multi-index (last axis fastest).
    for (size_t k = ndim; k-- > 0;) {
      if (++index[k] < shape[k]) {
        foffset += fstride[k];
        break;
      }
      foffset -= (shape[k] - 1) * fstride[k];
      index[k] = 0;
    }
  }
}

std::string ShapeRepr(const std::vector<int64_t>& shape) {
  std::string s = "(";
  for (size_t i = 0; i < shape.size(); ++i) {
    if (i) s += ", ";
    s += std::to_string(shape[i]);
  }
  if (shape.size() == 1) s += ",";
  return s + ")";
}

template <typename T>
void ConvertToFloat(const uint8_t* src, float* dst, size_t n) {
  for (size_t i = 0; i < n; ++i) {
    T v;
    std::memcpy(&v, src + i * sizeof(T), sizeof(T));
    dst[i] = static_cast<float>(v);
  }
}

// IEEE binary16 (MegaSaM's depths) through Eigen's half: exact, incl.
// subnormals, infinities and NaN.
void ConvertHalfToFloat(const uint8_t* src, float* dst, size_t n) {
  for (size_t i = 0; i < n; ++i) {
    uint16_t bits;
    std::memcpy(&bits, src + 2 * i, 2);
    dst[i] = static_cast<float>(Eigen::numext::bit_cast<Eigen::half>(bits));
  }
}

// The array of `header` from its raw data bytes (as stored): native byte
// order, C order, bools as 0/1.
NpyArray DecodeData(const NpyHeader& header, std::vector<uint8_t> raw) {
  NpyArray array;
  array.dtype = header.dtype;
  array.shape = header.shape;
  const size_t elem = NpyDtypeSize(header.dtype);
  const size_t count = raw.size() / elem;
  if (header.big_endian == HostIsLittleEndian())
    SwapBytes(raw.data(), count, elem);
  if (header.fortran_order && header.shape.size() > 1) {
    array.bytes.resize(raw.size());
    Reorder(raw.data(), array.bytes.data(), header.shape, elem,
            /*fortran_to_c=*/true);
  } else {
    array.bytes = std::move(raw);
  }
  if (array.dtype == NpyDtype::kBool) {
    for (uint8_t& b : array.bytes) b = b != 0;
  }
  return array;
}

// Throws unless `nbytes` of data are allowed and present.
void CheckDataSize(const std::string& path,
                   const NpyHeader& header,
                   uint64_t nbytes,
                   uint64_t available,
                   const NpyReadOptions& options) {
  if (nbytes > options.max_bytes) {
    ThrowInputError(path, "array of ", nbytes, " bytes (shape ",
                    ShapeRepr(header.shape), ") exceeds the limit of ",
                    options.max_bytes, " bytes");
  }
  if (available < nbytes) {
    ThrowInputError(path, "truncated: header says ", nbytes,
                    " bytes of data, file has ", available);
  }
}

}  // namespace

size_t NpyDtypeSize(NpyDtype dtype) {
  switch (dtype) {
    case NpyDtype::kFloat32:
      return 4;
    case NpyDtype::kFloat64:
      return 8;
    case NpyDtype::kUint8:
      return 1;
    case NpyDtype::kBool:
      return 1;
    case NpyDtype::kInt32:
      return 4;
    case NpyDtype::kInt64:
      return 8;
    case NpyDtype::kFloat16:
      return 2;
    case NpyDtype::kUint16:
      return 2;
  }
  return 0;
}

std::string NpyDtypeDescr(NpyDtype dtype) {
  switch (dtype) {
    case NpyDtype::kFloat32:
      return "<f4";
    case NpyDtype::kFloat64:
      return "<f8";
    case NpyDtype::kUint8:
      return "|u1";
    case NpyDtype::kBool:
      return "|b1";
    case NpyDtype::kInt32:
      return "<i4";
    case NpyDtype::kInt64:
      return "<i8";
    case NpyDtype::kFloat16:
      return "<f2";
    case NpyDtype::kUint16:
      return "<u2";
  }
  return "?";
}

int64_t NpyHeader::NumElements() const { return ShapeElements(shape); }

int64_t NpyArray::NumElements() const { return ShapeElements(shape); }

void NpyThrowDtypeMismatch(NpyDtype have, NpyDtype want) {
  throw InputError("npy array: dtype is " + NpyDtypeDescr(have) +
                   ", requested " + NpyDtypeDescr(want));
}

NpyArray NpyArray::Zeros(NpyDtype dtype, const std::vector<int64_t>& shape) {
  NpyArray array;
  array.dtype = dtype;
  array.shape = shape;
  const uint64_t size = CheckedByteSize("npy array", shape, dtype);
  array.bytes.assign(size, 0);
  return array;
}

NpyArray NpyArray::Float32(const std::vector<int64_t>& shape,
                           const float* data) {
  NpyArray array = Zeros(NpyDtype::kFloat32, shape);
  if (!array.bytes.empty())
    std::memcpy(array.bytes.data(), data, array.bytes.size());
  return array;
}

NpyArray NpyArray::Float64(const std::vector<int64_t>& shape,
                           const double* data) {
  NpyArray array = Zeros(NpyDtype::kFloat64, shape);
  if (!array.bytes.empty())
    std::memcpy(array.bytes.data(), data, array.bytes.size());
  return array;
}

NpyArray NpyArray::Uint8(const std::vector<int64_t>& shape,
                         const uint8_t* data) {
  NpyArray array = Zeros(NpyDtype::kUint8, shape);
  if (!array.bytes.empty())
    std::memcpy(array.bytes.data(), data, array.bytes.size());
  return array;
}

namespace {
// `path` opened with OpenInputFile (a regular file, never blocking) as a
// stdio stream; `*size` is its size.
std::unique_ptr<std::FILE, FileCloser> OpenNpyFile(const std::string& path,
                                                   uint64_t* size) {
  InputFile input = OpenInputFile(path);
  *size = input.size();
  std::unique_ptr<std::FILE, FileCloser> file(::fdopen(input.fd(), "rb"));
  if (!file) ThrowOpenError(path, errno);
  input.Release();  // the FILE owns the descriptor now
  return file;
}
}  // namespace

NpyHeader ReadNpyHeader(const std::string& path) {
  uint64_t file_size = 0;
  const auto file = OpenNpyFile(path, &file_size);
  return ReadHeader(path, file.get(), file_size);
}

NpyArray ReadNpy(const std::string& path, const NpyReadOptions& options) {
  uint64_t file_size = 0;
  const auto file = OpenNpyFile(path, &file_size);
  const NpyHeader header = ReadHeader(path, file.get(), file_size);
  const uint64_t nbytes = CheckedByteSize(path, header.shape, header.dtype);
  CheckDataSize(path, header, nbytes, file_size - header.data_offset, options);
  if (std::fseek(file.get(), static_cast<long>(header.data_offset), SEEK_SET) !=
      0) {
    ThrowInputError(path, "cannot seek to the data");
  }
  std::vector<uint8_t> raw(nbytes);
  if (nbytes > 0 && std::fread(raw.data(), 1, nbytes, file.get()) != nbytes) {
    ThrowInputError(path, "read error (file changed while reading?)");
  }
  return DecodeData(header, std::move(raw));
}

NpyHeader ParseNpyHeader(const std::string& what,
                         const uint8_t* data,
                         size_t size) {
  return ParseHeaderBytes(what, data, size, size);
}

NpyArray ParseNpy(const std::string& what,
                  const uint8_t* data,
                  size_t size,
                  const NpyReadOptions& options) {
  const NpyHeader header = ParseHeaderBytes(what, data, size, size);
  const uint64_t nbytes = CheckedByteSize(what, header.shape, header.dtype);
  CheckDataSize(what, header, nbytes, size - header.data_offset, options);
  const uint8_t* begin = data + header.data_offset;
  return DecodeData(header, std::vector<uint8_t>(begin, begin + nbytes));
}

NpyArray ParseNpy(const std::string& what,
                  std::vector<uint8_t>&& bytes,
                  const NpyReadOptions& options) {
  const size_t size = bytes.size();
  const NpyHeader header = ParseHeaderBytes(what, bytes.data(), size, size);
  const uint64_t nbytes = CheckedByteSize(what, header.shape, header.dtype);
  CheckDataSize(what, header, nbytes, size - header.data_offset, options);
  bytes.erase(bytes.begin(),
              bytes.begin() + static_cast<std::ptrdiff_t>(header.data_offset));
  bytes.resize(static_cast<size_t>(nbytes));
  return DecodeData(header, std::move(bytes));
}

NpyArray ReadNpyAsFloat32(const std::string& path,
                          const NpyReadOptions& options) {
  return ConvertNpyToFloat32(ReadNpy(path, options));
}

NpyArray ConvertNpyToFloat32(NpyArray in) {
  if (in.dtype == NpyDtype::kFloat32) return in;
  NpyArray out = NpyArray::Zeros(NpyDtype::kFloat32, in.shape);
  const size_t n = static_cast<size_t>(in.NumElements());
  float* dst = out.MutableData<float>();
  const uint8_t* src = in.bytes.data();
  switch (in.dtype) {
    case NpyDtype::kFloat32:
      break;
    case NpyDtype::kFloat64:
      ConvertToFloat<double>(src, dst, n);
      break;
    case NpyDtype::kFloat16:
      ConvertHalfToFloat(src, dst, n);
      break;
    case NpyDtype::kUint8:
    case NpyDtype::kBool:
      ConvertToFloat<uint8_t>(src, dst, n);
      break;
    case NpyDtype::kInt32:
      ConvertToFloat<int32_t>(src, dst, n);
      break;
    case NpyDtype::kInt64:
      ConvertToFloat<int64_t>(src, dst, n);
      break;
    case NpyDtype::kUint16:
      ConvertToFloat<uint16_t>(src, dst, n);
      break;
  }
  return out;
}

std::string NpyFileHeader(const std::string& path,
                          const NpyArray& array,
                          const NpyWriteOptions& options) {
  std::string header = NpyFileHeader(path, array.dtype, array.shape, options);
  const uint64_t nbytes = CheckedByteSize(path, array.shape, array.dtype);
  if (array.bytes.size() != nbytes) {
    ThrowInputError(path, "array holds ", array.bytes.size(),
                    " bytes but shape ", ShapeRepr(array.shape), " needs ",
                    nbytes);
  }
  return header;
}

std::string NpyFileHeader(const std::string& path,
                          NpyDtype dtype,
                          const std::vector<int64_t>& shape,
                          const NpyWriteOptions& options) {
  if (options.major_version < 1 || options.major_version > 3) {
    ThrowInputError(path, "unsupported .npy format version ",
                    options.major_version, " (supported: 1, 2, 3)");
  }
  if (shape.size() > static_cast<size_t>(kMaxDims)) {
    ThrowInputError(path, "cannot write ", shape.size(),
                    " dimensions (numpy's limit is 32)");
  }
  for (int64_t d : shape) {
    if (d < 0) ThrowInputError(path, "cannot write a negative dimension ", d);
  }
  CheckedByteSize(path, shape, dtype);
  const size_t elem = NpyDtypeSize(dtype);
  // Header exactly as numpy 1.24's _write_array_header + _wrap_header produce
  // it.
  std::string descr = NpyDtypeDescr(dtype);
  if (options.big_endian && elem > 1) descr[0] = '>';
  std::string dict = "{'descr': '" + descr + "', 'fortran_order': " +
                     (options.fortran_order ? "True" : "False") +
                     ", 'shape': " + ShapeRepr(shape) + ", }";
  if (!shape.empty()) {
    const int64_t growth_dim =
        options.fortran_order ? shape.back() : shape.front();
    const int digits = static_cast<int>(std::to_string(growth_dim).size());
    dict.append(static_cast<size_t>(std::max(0, kGrowthAxisMaxDigits - digits)),
                ' ');
  }
  const size_t prefix = options.major_version == 1 ? 10 : 12;
  const size_t hlen = dict.size() + 1;
  const size_t padlen = kArrayAlign - (prefix + hlen) % kArrayAlign;
  const size_t header_len = hlen + padlen;
  std::string out(kMagic, kMagicLen);
  out += static_cast<char>(options.major_version);
  out += '\0';
  out += static_cast<char>(header_len & 0xff);
  out += static_cast<char>((header_len >> 8) & 0xff);
  if (prefix == 12) {
    out += static_cast<char>((header_len >> 16) & 0xff);
    out += static_cast<char>((header_len >> 24) & 0xff);
  }
  out += dict;
  out.append(padlen, ' ');
  out += '\n';
  return out;
}

bool NpyDataIsStoredAsIs(const NpyArray& array,
                         const NpyWriteOptions& options) {
  const bool fortran = options.fortran_order && array.shape.size() > 1;
  const bool swap = options.big_endian == HostIsLittleEndian() &&
                    NpyDtypeSize(array.dtype) > 1;
  return !fortran && !swap;
}

std::string SerializeNpy(const std::string& path,
                         const NpyArray& array,
                         const NpyWriteOptions& options) {
  std::string out = NpyFileHeader(path, array, options);
  const size_t elem = NpyDtypeSize(array.dtype);
  const bool fortran = options.fortran_order && array.shape.size() > 1;
  const size_t nbytes = array.bytes.size();
  const size_t data_start = out.size();
  out.resize(data_start + nbytes);
  uint8_t* data = reinterpret_cast<uint8_t*>(&out[data_start]);
  if (fortran) {
    Reorder(array.bytes.data(), data, array.shape, elem,
            /*fortran_to_c=*/false);
  } else if (nbytes > 0) {
    std::memcpy(data, array.bytes.data(), nbytes);
  }
  if (options.big_endian == HostIsLittleEndian())
    SwapBytes(data, nbytes / elem, elem);
  return out;
}

void WriteNpy(const std::string& path,
              const NpyArray& array,
              const NpyWriteOptions& options) {
  WriteFileAtomic(path, SerializeNpy(path, array, options));
}

}  // namespace geodrive
