#include "dataset/waymo/tfrecord.h"

#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <limits>

#include "geometry/util/files.h"
#include "geometry/util/size_limits.h"
#include "geometry/util/status.h"

namespace geodrive {

namespace {

// CRC-32C by hand: Debian bookworm has no C++ package that offers it
// conveniently (abseil 20220623 predates absl/crc; protobuf and TurboJPEG keep
// theirs internal; libcrc32c would be one more dependency for 40 lines). SSE
// 4.2's crc32 instruction where the CPU has it, a 256-entry table (one byte a
// step, about 0.5-1 GB/s) otherwise; both give the same value (test).
constexpr uint32_t kCrc32cPolynomial = 0x82f63b78u;  // reflected Castagnoli

std::array<uint32_t, 256> MakeCrc32cTable() {
  std::array<uint32_t, 256> table{};
  for (uint32_t i = 0; i < 256; ++i) {
    uint32_t crc = i;
    for (int bit = 0; bit < 8; ++bit)
      crc = (crc >> 1) ^ ((crc & 1u) ? kCrc32cPolynomial : 0u);
    table[i] = crc;
  }
  return table;
}

constexpr int kHeaderBytes = 12;  // u64 length + u32 masked CRC
constexpr int kFooterBytes = 4;   // u32 masked CRC of the data

uint64_t LoadLe64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

uint32_t LoadLe32(const uint8_t* p) {
  return uint32_t{p[0]} | uint32_t{p[1]} << 8 | uint32_t{p[2]} << 16 |
         uint32_t{p[3]} << 24;
}

void StoreLe(uint64_t v, int bytes, std::string* out) {
  for (int i = 0; i < bytes; ++i)
    out->push_back(static_cast<char>(v >> (8 * i)));
}

// Reads exactly `size` bytes at `offset` of `fd`; "" on success, else why
// not (a read error, or an end of file before the size fstat gave: the file
// changed while it was read).
std::string ReadAt(int fd, uint64_t offset, void* out, size_t size) {
  uint8_t* p = static_cast<uint8_t*>(out);
  size_t done = 0;
  while (done < size) {
    const ssize_t n =
        ::pread(fd, p + done, size - done, static_cast<off_t>(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return std::strerror(errno);
    if (n == 0) return "the file ended early: it changed while being read";
    done += static_cast<size_t>(n);
  }
  return "";
}

}  // namespace

namespace {

// The table, one byte a step.
uint32_t Crc32cTable(const uint8_t* p, size_t size, uint32_t crc) {
  static const std::array<uint32_t, 256> table = MakeCrc32cTable();
  for (size_t i = 0; i < size; ++i)
    crc = table[(crc ^ p[i]) & 0xffu] ^ (crc >> 8);
  return crc;
}

#if defined(__x86_64__)
// SSE 4.2's crc32 instruction computes the same Castagnoli CRC, eight bytes
// a step (about 20x the table): a Waymo frame of a few MB is read and checked
// once per camera image and per LiDAR load.
__attribute__((target("sse4.2"))) uint32_t Crc32cSse42(const uint8_t* p,
                                                       size_t size,
                                                       uint32_t crc) {
  uint64_t c = crc;
  for (; size >= 8; size -= 8, p += 8) {
    uint64_t v;
    std::memcpy(&v, p, 8);
    c = __builtin_ia32_crc32di(c, v);
  }
  uint32_t c32 = static_cast<uint32_t>(c);
  for (; size > 0; --size, ++p) c32 = __builtin_ia32_crc32qi(c32, *p);
  return c32;
}
#endif

}  // namespace

uint32_t Crc32cPortable(const void* data, size_t size, uint32_t crc) {
  return ~Crc32cTable(static_cast<const uint8_t*>(data), size, ~crc);
}

uint32_t Crc32c(const void* data, size_t size, uint32_t crc) {
  const uint8_t* p = static_cast<const uint8_t*>(data);
#if defined(__x86_64__)
  static const bool sse42 = __builtin_cpu_supports("sse4.2");
  if (sse42) return ~Crc32cSse42(p, size, ~crc);
#endif
  return ~Crc32cTable(p, size, ~crc);
}

uint32_t MaskCrc32c(uint32_t crc) {
  return ((crc >> 15) | (crc << 17)) + 0xa282ead8u;
}

bool TfRecordReaderOptions::Check() const { return max_record_bytes > 0; }

TfRecordReader::TfRecordReader(const std::string& path,
                               const TfRecordReaderOptions& options)
    : file_(OpenInputFile(path)), options_(options) {
  GEODRIVE_CHECK_INPUT(
      options_.Check(), path,
      ": invalid TFRecord reader options (max_record_bytes 0)");
}

void TfRecordReader::Fail(const std::string& what) const {
  ThrowInputError(file_.path(), "record ", index_, " (at byte ", offset_,
                  "): ", what);
}

bool TfRecordReader::ReadHeader(uint64_t* length) {
  const uint64_t remaining = file_.size() - offset_;
  if (remaining == 0) return false;
  if (remaining < kHeaderBytes) {
    Fail(internal::StrCat("truncated header (", remaining, " of ", kHeaderBytes,
                          " bytes)"));
  }
  uint8_t header[kHeaderBytes];
  const std::string error = ReadAt(file_.fd(), offset_, header, kHeaderBytes);
  if (!error.empty()) Fail("cannot read the header (" + error + ")");
  *length = LoadLe64(header);
  if (options_.verify_crc) {
    const uint32_t stored = LoadLe32(header + 8);
    const uint32_t actual = MaskCrc32c(Crc32c(header, 8));
    if (stored != actual) {
      Fail(internal::StrCat("length CRC mismatch (stored 0x", std::hex, stored,
                            ", computed 0x", actual, std::dec, ", length ",
                            *length, "): not a TFRecord file or corrupt"));
    }
  }
  // The declared size, before anything is allocated: under the limit, then
  // within the bytes after the header (data + its CRC).
  CheckDeclaredSize(
      file_.path(),
      internal::StrCat("record ", index_, " (at byte ", offset_, ")"), *length,
      std::numeric_limits<uint64_t>::max(), options_.max_record_bytes);
  const uint64_t after_header = remaining - kHeaderBytes;
  if (*length > after_header || after_header - *length < kFooterBytes) {
    Fail(internal::StrCat("truncated data (the header declares ", *length,
                          " bytes + ", kFooterBytes, " of CRC, the file holds ",
                          after_header, " after the header)"));
  }
  return true;
}

bool TfRecordReader::Next(std::string* data) {
  uint64_t length = 0;
  if (!ReadHeader(&length)) return false;
  data->resize(length);
  uint8_t footer[kFooterBytes];
  const uint64_t data_offset = offset_ + kHeaderBytes;
  std::string error = ReadAt(file_.fd(), data_offset, data->data(), length);
  if (error.empty())
    error = ReadAt(file_.fd(), data_offset + length, footer, kFooterBytes);
  if (!error.empty()) Fail("cannot read the data (" + error + ")");
  if (options_.verify_crc) {
    const uint32_t stored = LoadLe32(footer);
    const uint32_t actual = MaskCrc32c(Crc32c(data->data(), length));
    if (stored != actual) {
      Fail(internal::StrCat("data CRC mismatch (stored 0x", std::hex, stored,
                            ", computed 0x", actual, std::dec, ", ", length,
                            " bytes)"));
    }
  }
  offset_ = data_offset + length + kFooterBytes;
  ++index_;
  return true;
}

bool TfRecordReader::Skip() {
  uint64_t length = 0;
  if (!ReadHeader(&length)) return false;
  offset_ += kHeaderBytes + length + kFooterBytes;
  ++index_;
  return true;
}

std::vector<std::string> ReadTfRecords(const std::string& path,
                                       const TfRecordReaderOptions& options) {
  TfRecordReader reader(path, options);
  std::vector<std::string> records;
  std::string data;
  while (reader.Next(&data)) records.push_back(std::move(data));
  return records;
}

int64_t CountTfRecords(const std::string& path,
                       const TfRecordReaderOptions& options) {
  TfRecordReader reader(path, options);
  while (reader.Skip()) {
  }
  return reader.index();
}

void AppendTfRecord(std::string_view data, std::string* out) {
  std::string header;
  StoreLe(data.size(), 8, &header);
  StoreLe(MaskCrc32c(Crc32c(header.data(), 8)), 4, &header);
  out->append(header);
  out->append(data.data(), data.size());
  std::string footer;
  StoreLe(MaskCrc32c(Crc32c(data.data(), data.size())), 4, &footer);
  out->append(footer);
}

void WriteTfRecordFile(const std::string& path,
                       const std::vector<std::string>& records) {
  std::string bytes;
  for (const std::string& r : records) AppendTfRecord(r, &bytes);
  WriteFileAtomic(path, bytes);
}

}  // namespace geodrive
