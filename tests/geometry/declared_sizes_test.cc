// Sizes a file declares are checked before anything is allocated or inflated
// (geometry/util/size_limits.h): hostile .npz archives (declared member sizes,
// compression ratios, stored members, shapes beyond the member, member
// counts, bzip2 bombs) and EXR headers (data windows against the file, the
// side limit, ratios, tile tables, oversized headers). Each is one InputError
// naming the file and the limit or the size the file holds.

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <zip.h>

#include <chrono>
#include <cstring>
#include <fstream>
#include <iterator>

#include "geometry/exr.h"
#include "geometry/npz.h"
#include "geometry/util/size_limits.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder, whose anonymous helpers share names.
namespace declared_sizes_test {

using ::testing::HasSubstr;

std::string NpyText(const NpyArray& array, const std::string& dir) {
  WriteNpy(dir + "/member.npy", array);
  return test::ReadFile(dir + "/member.npy");
}

// A zip of `members` (name -> bytes), each with `method`.
void WriteZip(const std::string& path,
              const std::vector<std::pair<std::string, std::string>>& members,
              int32_t method) {
  int error = 0;
  zip_t* z = zip_open(path.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
  ASSERT_NE(z, nullptr);
  for (const auto& [name, bytes] : members) {
    zip_source_t* src = zip_source_buffer(z, bytes.data(), bytes.size(), 0);
    const zip_int64_t i = zip_file_add(z, name.c_str(), src, ZIP_FL_OVERWRITE);
    ASSERT_GE(i, 0);
    zip_set_file_compression(z, static_cast<zip_uint64_t>(i), method, 0);
  }
  ASSERT_EQ(zip_close(z), 0);
}

void Put32(std::string* s, size_t at, uint32_t v) {
  for (int k = 0; k < 4; ++k) (*s)[at + k] = static_cast<char>(v >> (8 * k));
}

// Sets the uncompressed size of every entry, in the local headers and the
// central directory (so libzip's consistency check passes).
std::string WithDeclaredSize(std::string zip, uint32_t size) {
  for (size_t at = zip.find("PK\x03\x04"); at != std::string::npos;
       at = zip.find("PK\x03\x04", at + 4))
    Put32(&zip, at + 22, size);
  for (size_t at = zip.find("PK\x01\x02"); at != std::string::npos;
       at = zip.find("PK\x01\x02", at + 4))
    Put32(&zip, at + 24, size);
  return zip;
}

// The message of the InputError `read` throws ("" when it returns).
template <typename F>
std::string ErrorOf(F&& read) {
  try {
    read();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Opens `path` and reads every array.
void ReadAll(const std::string& path) {
  const NpzReader npz(path);
  for (const std::string& key : npz.Keys()) npz.Read(key);
}

TEST(DeclaredSizes, HostileNpzArchivesAreRefusedBeforeInflating) {
  const std::string dir = test::MakeTempDir("sizes_npz");
  std::vector<float> values(1000, 1.5f);
  const std::string member =
      NpyText(NpyArray::Float32({1000}, values.data()), dir);
  WriteZip(dir + "/good.npz", {{"depth.npy", member}}, ZIP_CM_DEFLATE);
  const std::string good = test::ReadFile(dir + "/good.npz");
  ASSERT_NO_THROW(ReadAll(dir + "/good.npz"));

  // 1. A deflated member declaring 3 GiB (the 976-byte archive of the
  // review): over the ratio, refused when the archive is opened.
  const std::string three_gib = dir + "/three_gib.npz";
  test::WriteFile(three_gib, WithDeclaredSize(good, 3u << 30));
  std::string e = ErrorOf([&] { ReadAll(three_gib); });
  std::cout << e << "\n";
  EXPECT_THAT(e, HasSubstr(three_gib + ": member 'depth.npy' declares " +
                           std::to_string(3ull << 30) + " bytes from "));
  EXPECT_THAT(e, HasSubstr("over the limit of 1100:1"));

  // 2. A stored member declaring more than it holds.
  WriteZip(dir + "/stored.npz", {{"depth.npy", member}}, ZIP_CM_STORE);
  const std::string stored = dir + "/stored_hostile.npz";
  test::WriteFile(stored,
                  WithDeclaredSize(test::ReadFile(dir + "/stored.npz"), 9000));
  e = ErrorOf([&] { ReadAll(stored); });
  std::cout << e << "\n";
  EXPECT_THAT(e, HasSubstr(stored + ": stored member 'depth.npy' declares "
                                    "9000 bytes but holds 4128"));

  // 3. A header whose shape is beyond the member's own (consistent) size.
  std::string text = member;
  text.replace(text.find("(1000,)"), 7, "(9000000,)");
  WriteZip(dir + "/shape.npz", {{"depth.npy", text}}, ZIP_CM_DEFLATE);
  e = ErrorOf([&] { ReadAll(dir + "/shape.npz"); });
  std::cout << e << "\n";
  EXPECT_THAT(e, HasSubstr(dir + "/shape.npz: depth.npy: the array declares "
                                 "36000000 bytes but the file holds only"));

  // 4. A bzip2 bomb: 64 MiB of zeros in a few hundred bytes (over 1100:1).
  if (zip_compression_method_supported(ZIP_CM_BZIP2, 1)) {
    std::string zeros =
        NpyText(NpyArray::Zeros(NpyDtype::kFloat32, {16 << 20}), dir);
    WriteZip(dir + "/bomb.npz", {{"depth.npy", zeros}}, ZIP_CM_BZIP2);
    e = ErrorOf([&] { ReadAll(dir + "/bomb.npz"); });
    std::cout << e << "\n";
    EXPECT_THAT(e, HasSubstr(dir + "/bomb.npz: member 'depth.npy' declares"));
    EXPECT_THAT(e, HasSubstr("over the limit of 1100:1"));
  }

  // 5. A member whose compressed size is past the end of the file.
  std::string past = good;
  for (size_t at = past.find("PK\x03\x04"); at != std::string::npos;
       at = past.find("PK\x03\x04", at + 4))
    Put32(&past, at + 18, 1 << 24);
  for (size_t at = past.find("PK\x01\x02"); at != std::string::npos;
       at = past.find("PK\x01\x02", at + 4))
    Put32(&past, at + 20, 1 << 24);
  test::WriteFile(dir + "/past.npz", past);
  e = ErrorOf([&] { ReadAll(dir + "/past.npz"); });
  std::cout << e << "\n";
  EXPECT_THAT(e, HasSubstr(dir + "/past.npz: "));

  // 6. Two entries sharing one member's data (an overlapping bomb): their
  // compressed bytes together exceed the file.
  WriteZip(dir + "/two.npz", {{"a.npy", member}, {"b.npy", member}},
           ZIP_CM_DEFLATE);
  std::string two = test::ReadFile(dir + "/two.npz");
  const size_t cd_a = two.find("PK\x01\x02");
  const size_t cd_b = two.find("PK\x01\x02", cd_a + 4);
  const size_t local_b = two.find("PK\x03\x04", 4);
  // b's local header renamed "a.npy"'s twin is not needed: point b at a's.
  std::memcpy(&two[cd_b + 42], &two[cd_a + 42], 4);
  (void)local_b;
  test::WriteFile(dir + "/overlap.npz", two);
  e = ErrorOf([&] { ReadAll(dir + "/overlap.npz"); });
  std::cout << e << "\n";
  EXPECT_THAT(e, HasSubstr(dir + "/overlap.npz: "));
}

TEST(DeclaredSizes, NpzMemberCountIsLimitedAndListedInLinearTime) {
  const std::string dir = test::MakeTempDir("sizes_npz_members");
  const std::string member =
      NpyText(NpyArray::Zeros(NpyDtype::kUint8, {1}), dir);
  // Under the limit: opening and looking every member up is linear (the
  // quadratic list took minutes at 200k members).
  std::vector<std::pair<std::string, std::string>> members;
  for (int i = 0; i < 60000; ++i)
    members.push_back({"m" + std::to_string(i) + ".npy", member});
  WriteZip(dir + "/many.npz", members, ZIP_CM_STORE);
  const auto start = std::chrono::steady_clock::now();
  {
    const NpzReader npz(dir + "/many.npz");
    ASSERT_EQ(npz.Keys().size(), 60000u);
    for (const std::string& key : npz.Keys()) ASSERT_TRUE(npz.Has(key));
    EXPECT_EQ(npz.Read("m59999").bytes.size(), 1u);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  std::cout << "60000 members opened and looked up in " << seconds << " s\n";
  EXPECT_LT(seconds, 20.0);
  // Over the limit: refused from the count.
  for (int i = 60000; i < 65537; ++i)
    members.push_back({"m" + std::to_string(i) + ".npy", member});
  WriteZip(dir + "/too_many.npz", members, ZIP_CM_STORE);
  const std::string e = ErrorOf([&] { NpzReader(dir + "/too_many.npz"); });
  EXPECT_EQ(e, dir +
                   "/too_many.npz: the archive declares 65537, over the "
                   "limit of 65536");
}

// An EXR file: magic, version (flags), the attributes, the end of the header,
// then `tail` bytes (offset table and chunks, or nothing).
struct ExrAttribute {
  std::string name, type, value;
};

std::string Le32(int32_t v) {
  std::string s(4, '\0');
  Put32(&s, 0, static_cast<uint32_t>(v));
  return s;
}

std::string ExrFile(const std::vector<ExrAttribute>& attributes,
                    size_t tail,
                    uint32_t flags = 0) {
  std::string out = Le32(20000630) + Le32(static_cast<int32_t>(2 | flags));
  for (const ExrAttribute& a : attributes) {
    out += a.name + '\0' + a.type + '\0' +
           Le32(static_cast<int32_t>(a.value.size())) + a.value;
  }
  out += '\0';
  return out + std::string(tail, '\0');
}

std::string Box(int x0, int y0, int x1, int y1) {
  return Le32(x0) + Le32(y0) + Le32(x1) + Le32(y1);
}

// One FLOAT channel "Z".
std::string OneChannel() {
  return std::string("Z") + '\0' + Le32(2) + std::string(4, '\0') + Le32(1) +
         Le32(1) + '\0';
}

std::vector<ExrAttribute> Header(int w, int h, int compression) {
  return {{"channels", "chlist", OneChannel()},
          {"compression", "compression", std::string(1, char(compression))},
          {"dataWindow", "box2i", Box(0, 0, w - 1, h - 1)},
          {"displayWindow", "box2i", Box(0, 0, w - 1, h - 1)},
          {"lineOrder", "lineOrder", std::string(1, '\0')},
          {"pixelAspectRatio", "float", std::string("\0\0\x80\x3f", 4)},
          {"screenWindowCenter", "v2f", std::string(8, '\0')},
          {"screenWindowWidth", "float", std::string("\0\0\x80\x3f", 4)}};
}

TEST(DeclaredSizes, HostileExrHeadersAreRefusedBeforeAllocating) {
  const std::string dir = test::MakeTempDir("sizes_exr");
  // A real file still reads (ZIP compression, the header parsed as written).
  cv::Mat depth(48, 64, CV_32FC1, cv::Scalar(2.5f));
  WriteExr(dir + "/good.exr", depth, {"Z"});
  EXPECT_EQ(ReadExr(dir + "/good.exr", {"Z"}).at<float>(47, 63), 2.5f);
  EXPECT_EQ(ExrChannels(dir + "/good.exr"), std::vector<std::string>{"Z"});
  cv::Mat zeros(2048, 2048, CV_32FC1, cv::Scalar(0.f));
  WriteExr(dir + "/zeros.exr", zeros, {"Z"});  // ZIP's best ratio still reads
  EXPECT_EQ(ReadExr(dir + "/zeros.exr", {"Z"}).rows, 2048);

  const auto expect = [&](const std::string& name, const std::string& bytes,
                          const std::string& what) {
    const std::string path = dir + "/" + name;
    test::WriteFile(path, bytes);
    for (int k = 0; k < 2; ++k) {
      const std::string e = ErrorOf([&] {
        if (k == 0) {
          ReadExr(path, {"Z"});
        } else {
          ExrChannels(path);
        }
      });
      std::cout << e << "\n";
      EXPECT_THAT(e, HasSubstr(path + ": " + what));
    }
  };
  // 1. 16384 x 16384 uncompressed with only its offset table (131 KB, which
  // allocated 1 GB), then with room for every chunk's header but no pixels.
  expect("offsets.exr", ExrFile(Header(16384, 16384, 0), 16384 * 8),
         "the EXR header's chunk table declares 262144 bytes but the file "
         "holds only 131072");
  expect("window.exr", ExrFile(Header(16384, 16384, 0), 16384 * 16 + 1000),
         "the EXR data window declares 1073741824 bytes but the file holds "
         "only");
  // 2. A side over the limit.
  expect("side.exr", ExrFile(Header(100000, 4, 0), 4096),
         "data window 100000x4 is outside the reader's limit (1..16384 a "
         "side, 268435456 pixels)");
  // 3. An inverted window.
  {
    std::vector<ExrAttribute> h = Header(8, 8, 0);
    h[2].value = Box(10, 10, 0, 0);
    expect("inverted.exr", ExrFile(h, 4096), "data window -9x-9");
  }
  // 4. ZIP-compressed 16384 x 16384 from 80 KB of chunks: over the ratio.
  expect("ratio.exr", ExrFile(Header(16384, 16384, 3), 80000),
         "the EXR data window declares 1073741824 bytes from ");
  // 5. Tiles of 1 x 1 over 16384 x 16384: an offset table of 2 GiB.
  {
    std::vector<ExrAttribute> h = Header(16384, 16384, 3);
    h.push_back({"tiles", "tiledesc", Le32(1) + Le32(1) + std::string(1, 0)});
    expect("tiles.exr", ExrFile(h, 100000, 0x200),
           "the EXR header's chunk table declares 4294967296 bytes but the "
           "file holds only");
  }
  // 5a. A real tiled file whose 64 x 64 tiles are larger than its 4 x 4
  // window (OpenEXR's tile buffer, 16 KB, is under the ratio-free bytes):
  // one tile, clipped to the window, still reads.
  {
    std::vector<ExrAttribute> h = Header(4, 4, 0);
    h.push_back({"tiles", "tiledesc", Le32(64) + Le32(64) + std::string(1, 0)});
    std::string bytes = ExrFile(h, 0, 0x200);
    std::string offset(8, '\0');
    Put32(&offset, 0, static_cast<uint32_t>(bytes.size() + 8));
    bytes += offset + Le32(0) + Le32(0) + Le32(0) + Le32(0) + Le32(64);
    for (int k = 0; k < 16; ++k) bytes += Le32(0x40200000);  // 2.5f
    test::WriteFile(dir + "/small_window.exr", bytes);
    EXPECT_EQ(ReadExr(dir + "/small_window.exr", {"Z"}).at<float>(3, 3), 2.5f);
  }
  // 5b. Tiles larger than the window: OpenEXR sizes a tile's buffer by the
  // tile (fuzz_exr_header's third finding, tiles of 1 x 469762048 over 4 x 4,
  // allocated 1.88 GB), then within the side limit but over the ratio.
  {
    std::vector<ExrAttribute> h = Header(4, 4, 0);
    h.push_back(
        {"tiles", "tiledesc", Le32(1) + Le32(469762048) + std::string(1, 0)});
    expect("tall_tiles.exr", ExrFile(h, 4096, 0x200),
           "EXR tiles of 1x469762048 are outside the reader's limit (1..16384 "
           "a side)");
    h.back().value = Le32(16384) + Le32(16384) + std::string(1, 0);
    expect("big_tiles.exr", ExrFile(h, 4096, 0x200),
           "EXR data window 4x4 in whole tiles of 16384x16384 is 16384x16384 "
           "pixels, 1073741824 bytes at 4 bytes a pixel (OpenEXR's buffers), "
           "over 1100 times the 4096 bytes after the header");
  }
  // 5c. One row of DWAB (256 scan lines a block) 16384 wide: a block's
  // buffer is 256 rows whatever the window's height.
  expect("dwab_row.exr", ExrFile(Header(16384, 1, 9), 4096),
         "EXR data window 16384x1 in whole blocks of 256 scan lines "
         "(compression 9) is 16384x256 pixels, 16777216 bytes at 4 bytes a "
         "pixel (OpenEXR's buffers), over 1100 times the 4096 bytes after the "
         "header");
  // 6. An attribute declaring 2^31 - 1 bytes in a small file.
  {
    std::vector<ExrAttribute> h = Header(8, 8, 0);
    std::string bytes = ExrFile(h, 0);
    bytes.insert(8, std::string("owner") + '\0' + "string" + '\0' +
                        Le32(0x7fffffff) + "x");
    expect("attribute.exr", bytes, "truncated EXR header");
  }
  // 6b. A fixed-size value declaring another size (a fuzzed chunkCount of 10
  // bytes: OpenEXR and this parser would read the rest of the header
  // differently, and OpenEXR allocated a huge table from it).
  {
    std::vector<ExrAttribute> h = Header(8, 8, 0);
    h.push_back({"chunkCount", "int", Le32(8) + std::string(6, '\0')});
    expect("fixed.exr", ExrFile(h, 4096),
           "EXR attribute 'chunkCount' of type int declares 10 bytes (the "
           "type has 4)");
  }
  // 6c. A channel list declaring more bytes than its channels hold (OpenEXR
  // reads the list by its structure and would read the rest of the header
  // from another place than the check).
  {
    std::vector<ExrAttribute> h = Header(8, 8, 0);
    h[0].value += std::string(4, '\0');
    expect("chlist.exr", ExrFile(h, 4096),
           "EXR channel list 'channels' declares 23 bytes but its channels end "
           "at byte 19");
  }
  // 7. A header longer than 1 MiB.
  {
    std::vector<ExrAttribute> h = Header(8, 8, 0);
    h.push_back({"comments", "string", std::string(2 << 20, 'a')});
    expect("long.exr", ExrFile(h, 4096),
           "the EXR header is longer than the limit of 1048576 bytes");
  }
  // 8. Four channels of 16384 x 16384 in a multi-part file's first part.
  {
    std::vector<ExrAttribute> h = Header(16384, 16384, 0);
    h.push_back({"chunkCount", "int", Le32(16384)});
    h.push_back({"name", "string", "p"});
    h.push_back({"type", "string", "scanlineimage"});
    std::string bytes = ExrFile(h, 0, 0x1000);
    bytes += '\0';  // the empty header that ends the parts
    bytes += std::string(16384 * 16 + 1000, '\0');
    expect("multipart.exr", bytes,
           "the EXR data window declares 1073741824 bytes but the file holds "
           "only");
  }
}

}  // namespace declared_sizes_test
}  // namespace geodrive
