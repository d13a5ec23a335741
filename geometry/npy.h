#pragma once
// NumPy .npy reading and writing (format versions 1.0, 2.0, 3.0).
//
// Supported dtypes: <f4 <f8 <f2 |u1 |b1 <i4 <i8 <u2 (and their big-endian '>'
// forms on read). Arrays are returned in native (little-endian) byte order and
// C (row-major) order: Fortran-order and big-endian files are converted on
// read. Every failure throws InputError naming the file.

#include <cstdint>
#include <string>
#include <vector>

namespace geodrive {

enum class NpyDtype {
  kFloat32,
  kFloat64,
  kUint8,
  kBool,
  kInt32,
  kInt64,
  kUint16,
  kFloat16
};

// Size in bytes of one element.
size_t NpyDtypeSize(NpyDtype dtype);
// numpy descr string in little-endian form: "<f4", "|u1", ...
std::string NpyDtypeDescr(NpyDtype dtype);

// What the header of a .npy file says (as stored: byte order and memory order
// of the file).
struct NpyHeader {
  int major_version = 1;
  int minor_version = 0;
  NpyDtype dtype = NpyDtype::kFloat32;
  bool big_endian = false;
  bool fortran_order = false;
  std::vector<int64_t> shape;
  size_t data_offset = 0;  // bytes from the start of the file to the data

  int64_t NumElements() const;
};

// An array in native byte order and C order.
struct NpyArray {
  NpyDtype dtype = NpyDtype::kFloat32;
  std::vector<int64_t> shape;
  std::vector<uint8_t> bytes;  // NumElements() * NpyDtypeSize(dtype) bytes

  int64_t NumElements() const;
  // Typed view; throws InputError if T does not match dtype (bool reads as
  // uint8_t).
  template <typename T>
  const T* Data() const;
  template <typename T>
  T* MutableData();

  // Helpers to build arrays for writing.
  static NpyArray Float32(const std::vector<int64_t>& shape, const float* data);
  static NpyArray Float64(const std::vector<int64_t>& shape,
                          const double* data);
  static NpyArray Uint8(const std::vector<int64_t>& shape, const uint8_t* data);
  static NpyArray Zeros(NpyDtype dtype, const std::vector<int64_t>& shape);
};

// Limits that protect against absurd headers (a shape that would need
// terabytes).
struct NpyReadOptions {
  // Maximum number of bytes of array data accepted (default 8 GiB).
  uint64_t max_bytes = 8ull << 30;
};

// Reads only the header (cheap; used by `geodrive info`).
NpyHeader ReadNpyHeader(const std::string& path);
// Reads the whole array.
NpyArray ReadNpy(const std::string& path, const NpyReadOptions& options = {});
// Reads a float array of any supported numeric dtype converted to float32
// (bool/uint8/... too).
NpyArray ReadNpyAsFloat32(const std::string& path,
                          const NpyReadOptions& options = {});
// Any supported dtype converted to float32 (float16 exactly, through
// Eigen::half).
NpyArray ConvertNpyToFloat32(NpyArray array);

// The same from a .npy held in memory (an .npz member, geometry/npz.h); `what`
// names it in errors ("file.npz: depth.npy").
NpyHeader ParseNpyHeader(const std::string& what,
                         const uint8_t* data,
                         size_t size);
NpyArray ParseNpy(const std::string& what,
                  const uint8_t* data,
                  size_t size,
                  const NpyReadOptions& options = {});
// The same, taking the bytes: the array's data stay in their buffer (moved
// to its front) instead of being copied, for large members.
NpyArray ParseNpy(const std::string& what,
                  std::vector<uint8_t>&& bytes,
                  const NpyReadOptions& options = {});

struct NpyWriteOptions {
  int major_version =
      1;  // 1, 2 or 3 (3 only changes the header encoding to utf-8)
  bool fortran_order = false;  // write column-major data
  bool big_endian = false;     // write big-endian data (descr '>f4' ...)
};
// The header of the .npy file of `array` (magic, version, dictionary,
// padding): the first bytes of SerializeNpy's output. `path` only names the
// file in errors; throws InputError on a bad shape or size.
std::string NpyFileHeader(const std::string& path,
                          const NpyArray& array,
                          const NpyWriteOptions& options = {});
// The same header for data of `dtype` and `shape` held elsewhere.
std::string NpyFileHeader(const std::string& path,
                          NpyDtype dtype,
                          const std::vector<int64_t>& shape,
                          const NpyWriteOptions& options = {});
// True when the file's data are array.bytes unchanged (C order or one
// dimension, the host's byte order): the file is NpyFileHeader + bytes.
bool NpyDataIsStoredAsIs(const NpyArray& array,
                         const NpyWriteOptions& options = {});
// The whole .npy file of `array` (what WriteNpy writes); `path` only names
// the file in errors. Throws InputError on a bad shape or size.
std::string SerializeNpy(const std::string& path,
                         const NpyArray& array,
                         const NpyWriteOptions& options = {});
// Writes `array` to `path` atomically (temporary file + rename). Throws
// InputError on failure.
void WriteNpy(const std::string& path,
              const NpyArray& array,
              const NpyWriteOptions& options = {});

// ---- Implementation ----
template <typename T>
struct NpyTypeOf;
template <>
struct NpyTypeOf<float> {
  static constexpr NpyDtype value = NpyDtype::kFloat32;
};
template <>
struct NpyTypeOf<double> {
  static constexpr NpyDtype value = NpyDtype::kFloat64;
};
template <>
struct NpyTypeOf<uint8_t> {
  static constexpr NpyDtype value = NpyDtype::kUint8;
};
template <>
struct NpyTypeOf<int32_t> {
  static constexpr NpyDtype value = NpyDtype::kInt32;
};
template <>
struct NpyTypeOf<int64_t> {
  static constexpr NpyDtype value = NpyDtype::kInt64;
};
template <>
struct NpyTypeOf<uint16_t> {
  static constexpr NpyDtype value = NpyDtype::kUint16;
};

void NpyThrowDtypeMismatch(NpyDtype have, NpyDtype want);

template <typename T>
const T* NpyArray::Data() const {
  constexpr NpyDtype want = NpyTypeOf<T>::value;
  if (!(dtype == want ||
        (want == NpyDtype::kUint8 && dtype == NpyDtype::kBool))) {
    NpyThrowDtypeMismatch(dtype, want);
  }
  return reinterpret_cast<const T*>(bytes.data());
}
template <typename T>
T* NpyArray::MutableData() {
  return const_cast<T*>(static_cast<const NpyArray*>(this)->Data<T>());
}

}  // namespace geodrive
