// TFRecord framing (dataset/waymo/tfrecord.h): CRC-32C against published
// check values, a write/read round trip, and hostile files -- a truncated
// header or data, a bad length or data CRC, a length of 2^60 -- each one
// InputError naming the file and the record index, the size checked before
// anything is allocated.

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "dataset/waymo/tfrecord.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder.
namespace waymo_tfrecord_test {

using ::testing::AllOf;
using ::testing::HasSubstr;

// The message of the InputError that reading every record of `path` throws.
std::string ReadError(const std::string& path) {
  try {
    ReadTfRecords(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

std::string Framed(const std::vector<std::string>& records) {
  std::string bytes;
  for (const std::string& r : records) AppendTfRecord(r, &bytes);
  return bytes;
}

TEST(WaymoTfRecord, Crc32cMatchesTheCheckValues) {
  // RFC 3720 B.4 and the usual "123456789" check value.
  EXPECT_EQ(Crc32c("123456789", 9), 0xe3069283u);
  const std::string zeros(32, '\0');
  EXPECT_EQ(Crc32c(zeros.data(), zeros.size()), 0x8a9136aau);
  const std::string ones(32, '\xff');
  EXPECT_EQ(Crc32c(ones.data(), ones.size()), 0x62a8ab43u);
  // Continuing a CRC equals one pass over the whole.
  EXPECT_EQ(Crc32c("6789", 4, Crc32c("12345", 5)), 0xe3069283u);
  EXPECT_EQ(MaskCrc32c(0), 0xa282ead8u);
  // The instruction path (where the CPU has it) and the table agree on every
  // length and alignment, continued or not.
  std::string bytes(1031, '\0');
  for (size_t i = 0; i < bytes.size(); ++i)
    bytes[i] = static_cast<char>((i * 2654435761u) >> 13);
  EXPECT_EQ(Crc32cPortable("123456789", 9), 0xe3069283u);
  for (size_t start = 0; start < 9; ++start) {
    for (size_t size : {0, 1, 7, 8, 9, 63, 64, 1000}) {
      const char* p = bytes.data() + start;
      EXPECT_EQ(Crc32c(p, size), Crc32cPortable(p, size))
          << start << " " << size;
      EXPECT_EQ(Crc32c(p, size, 0x12345678u),
                Crc32cPortable(p, size, 0x12345678u));
    }
  }
}

TEST(WaymoTfRecord, RoundTripIsExact) {
  const std::string dir = test::MakeTempDir("waymo_tfrecord");
  const std::string path = dir + "/three.tfrecord";
  std::string big(100000, '\0');
  for (size_t i = 0; i < big.size(); ++i) big[i] = static_cast<char>(i * 7);
  const std::vector<std::string> records = {"first", "", big};
  WriteTfRecordFile(path, records);
  // 12 + 4 bytes of framing per record.
  EXPECT_EQ(test::ReadFile(path).size(), 5 + 0 + big.size() + 3 * 16);
  EXPECT_EQ(ReadTfRecords(path), records);
  EXPECT_EQ(CountTfRecords(path), 3);
  TfRecordReader reader(path);
  std::string data;
  ASSERT_TRUE(reader.Next(&data));
  ASSERT_TRUE(reader.Skip());
  ASSERT_TRUE(reader.Next(&data));
  EXPECT_EQ(data, big);
  EXPECT_EQ(reader.index(), 3);
  EXPECT_FALSE(reader.Next(&data));
  // An empty file holds no record.
  test::WriteFile(dir + "/empty.tfrecord", "");
  EXPECT_TRUE(ReadTfRecords(dir + "/empty.tfrecord").empty());
}

TEST(WaymoTfRecord, TruncatedRecordsNameFileAndIndex) {
  const std::string dir = test::MakeTempDir("waymo_tfrecord");
  const std::string good = Framed({"alpha", "beta"});
  // Cut inside the second record's header (5 of its 12 bytes).
  const std::string header_cut = dir + "/header_cut.tfrecord";
  test::WriteFile(header_cut, good.substr(0, 21 + 5));
  EXPECT_THAT(ReadError(header_cut),
              AllOf(HasSubstr(header_cut), HasSubstr("record 1 (at byte 21)"),
                    HasSubstr("truncated header (5 of 12 bytes)")));
  // Cut inside the second record's data.
  const std::string data_cut = dir + "/data_cut.tfrecord";
  test::WriteFile(data_cut, good.substr(0, good.size() - 6));
  EXPECT_THAT(ReadError(data_cut),
              AllOf(HasSubstr(data_cut), HasSubstr("record 1"),
                    HasSubstr("truncated data")));
  // The data CRC missing.
  const std::string crc_cut = dir + "/crc_cut.tfrecord";
  test::WriteFile(crc_cut, good.substr(0, good.size() - 1));
  EXPECT_THAT(ReadError(crc_cut),
              AllOf(HasSubstr("record 1"), HasSubstr("truncated data")));
}

TEST(WaymoTfRecord, BadCrcsNameFileAndIndex) {
  const std::string dir = test::MakeTempDir("waymo_tfrecord");
  const std::string good = Framed({"alpha", "beta", "gamma"});
  // Record 1 starts at 5 + 16 = 21: its length CRC at 29..32, data at 33.
  std::string bytes = good;
  bytes[30] ^= 0x01;
  const std::string length_crc = dir + "/length_crc.tfrecord";
  test::WriteFile(length_crc, bytes);
  EXPECT_THAT(ReadError(length_crc),
              AllOf(HasSubstr(length_crc), HasSubstr("record 1 (at byte 21)"),
                    HasSubstr("length CRC mismatch")));
  bytes = good;
  bytes[34] ^= 0x20;  // "beta" -> "bEta"
  const std::string data_crc = dir + "/data_crc.tfrecord";
  test::WriteFile(data_crc, bytes);
  EXPECT_THAT(ReadError(data_crc),
              AllOf(HasSubstr(data_crc), HasSubstr("record 1 (at byte 21)"),
                    HasSubstr("data CRC mismatch")));
  // Without CRC checks the flipped byte reads through.
  TfRecordReaderOptions options;
  options.verify_crc = false;
  EXPECT_EQ(ReadTfRecords(data_crc, options)[1], "bEta");
  // Skip checks the length CRC but not the data's.
  EXPECT_EQ(CountTfRecords(data_crc), 3);
}

TEST(WaymoTfRecord, LengthOf2To60IsRefusedBeforeAllocating) {
  const std::string dir = test::MakeTempDir("waymo_tfrecord");
  // A valid first record, then a header declaring 2^60 bytes with a correct
  // length CRC, then a few bytes: a reader that allocated first would ask
  // for an exabyte.
  std::string bytes = Framed({"ok"});
  std::string header;
  const uint64_t length = uint64_t{1} << 60;
  for (int i = 0; i < 8; ++i)
    header.push_back(static_cast<char>(length >> (8 * i)));
  const uint32_t crc = MaskCrc32c(Crc32c(header.data(), 8));
  for (int i = 0; i < 4; ++i)
    header.push_back(static_cast<char>(crc >> (8 * i)));
  bytes += header + "tail";
  const std::string path = dir + "/huge.tfrecord";
  test::WriteFile(path, bytes);
  EXPECT_THAT(ReadError(path),
              AllOf(HasSubstr(path), HasSubstr("record 1 (at byte 18)"),
                    HasSubstr("declares 1152921504606846976 bytes, over the "
                              "limit of 1073741824 bytes")));
  // Under the limit but beyond the file: truncated, also before allocating.
  TfRecordReaderOptions options;
  options.max_record_bytes = uint64_t{1} << 62;
  try {
    ReadTfRecords(path, options);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), AllOf(HasSubstr("record 1"),
                                HasSubstr("truncated data (the header declares "
                                          "1152921504606846976 bytes")));
  }
}

TEST(WaymoTfRecord, NotAFileIsAnInputError) {
  const std::string dir = test::MakeTempDir("waymo_tfrecord");
  EXPECT_THROW(TfRecordReader(dir + "/missing.tfrecord"), InputError);
  EXPECT_THROW(TfRecordReader{dir}, InputError);
}

}  // namespace waymo_tfrecord_test
}  // namespace geodrive
