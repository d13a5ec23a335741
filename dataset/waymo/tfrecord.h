#pragma once
// TFRecord files: the framing of Waymo Open Dataset segments (and of every
// TensorFlow record file). Each record is
//
//   u64 little-endian length | u32 masked CRC-32C of those 8 bytes |
//   length bytes of data     | u32 masked CRC-32C of the data
//
// with mask(crc) = ((crc >> 15) | (crc << 17)) + 0xa282ead8 (tensorflow/tsl
// lib/hash/crc32c.h). Every declared length is checked against the bytes the
// file still holds and against TfRecordReaderOptions::max_record_bytes before
// anything is allocated; every error is one InputError naming the file and the
// record index.

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "geometry/util/input_file.h"
#include "geometry/util/size_limits.h"

namespace geodrive {

// CRC-32C (Castagnoli, reflected polynomial 0x82f63b78) of `size` bytes,
// continuing from `crc` (0 to start).
uint32_t Crc32c(const void* data, size_t size, uint32_t crc = 0);
// The same with the byte table only (what Crc32c uses on CPUs without SSE
// 4.2's crc32 instruction; for tests).
uint32_t Crc32cPortable(const void* data, size_t size, uint32_t crc = 0);
// TFRecord's masking of a stored CRC.
uint32_t MaskCrc32c(uint32_t crc);

struct TfRecordReaderOptions {
  // The largest record read, in bytes: a longer declared length is an error
  // before any allocation (SizeLimits: 1 GiB).
  uint64_t max_record_bytes = SizeLimits::kMaxTfRecordBytes;
  // Check both CRCs of every record (a bad CRC is an error).
  bool verify_crc = true;

  bool Check() const;
};

// Reads the records of one file in order.
class TfRecordReader {
 public:
  // Opens `path` (OpenInputFile: InputError for a missing or non-regular
  // file).
  explicit TfRecordReader(
      const std::string& path,
      const TfRecordReaderOptions& options = TfRecordReaderOptions());

  // The next record's data into *data; false at the end of the file (no byte
  // left). Throws InputError "<file>: record <i> (at byte <b>): <what>" for a
  // truncated header or data, a length or data CRC mismatch, or a length over
  // the limit.
  bool Next(std::string* data);
  // Skips the next record without reading its data or checking its data CRC
  // (its length and length CRC are checked); false at the end of the file.
  bool Skip();

  // Index of the record the next Next() returns (the number read so far).
  int64_t index() const { return index_; }
  const std::string& path() const { return file_.path(); }

 private:
  // Reads and checks the header of the record at offset_; false at the end.
  bool ReadHeader(uint64_t* length);
  [[noreturn]] void Fail(const std::string& what) const;

  InputFile file_;
  TfRecordReaderOptions options_;
  uint64_t offset_ = 0;
  int64_t index_ = 0;
};

// Every record of `path`.
std::vector<std::string> ReadTfRecords(
    const std::string& path,
    const TfRecordReaderOptions& options = TfRecordReaderOptions());
// The number of records of `path` (headers and length CRCs checked, data
// skipped).
int64_t CountTfRecords(
    const std::string& path,
    const TfRecordReaderOptions& options = TfRecordReaderOptions());

// Appends one framed record holding `data` to *out.
void AppendTfRecord(std::string_view data, std::string* out);
// Writes `records` as the TFRecord file `path` (atomically: a temporary file
// renamed into place).
void WriteTfRecordFile(const std::string& path,
                       const std::vector<std::string>& records);

}  // namespace geodrive
