// .npz archives (geometry/npz.h): members stored and deflated (written here
// with libzip, as numpy.savez and numpy.savez_compressed write them), float16
// members, damaged and hostile archives; and an archive written by NumPy.

#include "geometry/npz.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <zip.h>

#include <Eigen/Core>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
namespace {

using ::testing::HasSubstr;

// The bytes of a .npy (format 1.0) of `array`.
std::vector<uint8_t> NpyBytes(const NpyArray& array, const std::string& dir) {
  const std::string path = dir + "/tmp.npy";
  WriteNpy(path, array);
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

// Writes `members` (name -> bytes) into a zip, deflated or stored.
void WriteZip(
    const std::string& path,
    const std::vector<std::pair<std::string, std::vector<uint8_t>>>& members,
    bool deflate) {
  int error = 0;
  zip_t* z = zip_open(path.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
  ASSERT_NE(z, nullptr);
  for (const auto& [name, bytes] : members) {
    zip_source_t* src = zip_source_buffer(z, bytes.data(), bytes.size(), 0);
    const zip_int64_t i = zip_file_add(z, name.c_str(), src, ZIP_FL_OVERWRITE);
    ASSERT_GE(i, 0);
    zip_set_file_compression(z, static_cast<zip_uint64_t>(i),
                             deflate ? ZIP_CM_DEFLATE : ZIP_CM_STORE, 0);
  }
  ASSERT_EQ(zip_close(z), 0);
}

// A (2, 3, 4) float32 depth, a float16 copy of it, a uint8 image.
struct Arrays {
  std::vector<float> depth;
  NpyArray depth32, depth16, image;
  Arrays() {
    for (int i = 0; i < 24; ++i) depth.push_back(0.25f * i + 1.0f);
    depth32 = NpyArray::Float32({2, 3, 4}, depth.data());
    depth16 = NpyArray::Zeros(NpyDtype::kFloat16, {2, 3, 4});
    for (int i = 0; i < 24; ++i) {
      // Multiples of 0.25 up to 6.75 are exact in binary16.
      const uint16_t bits =
          Eigen::numext::bit_cast<uint16_t>(Eigen::half(depth[i]));
      std::memcpy(depth16.bytes.data() + 2 * i, &bits, 2);
    }
    std::vector<uint8_t> rgb(2 * 2 * 3);
    for (size_t i = 0; i < rgb.size(); ++i)
      rgb[i] = static_cast<uint8_t>(i * 20);
    image = NpyArray::Uint8({2, 2, 3}, rgb.data());
  }
};

TEST(Npz, StoredAndDeflatedMembersReadBack) {
  const std::string dir = test::MakeTempDir("npz_roundtrip");
  const Arrays a;
  for (bool deflate : {false, true}) {
    const std::string path = dir + (deflate ? "/deflated.npz" : "/stored.npz");
    WriteZip(path,
             {{"depth.npy", NpyBytes(a.depth32, dir)},
              {"depth16.npy", NpyBytes(a.depth16, dir)},
              {"images.npy", NpyBytes(a.image, dir)}},
             deflate);
    EXPECT_TRUE(LooksLikeZip(path));
    const NpzReader npz(path);
    EXPECT_THAT(npz.Keys(),
                ::testing::ElementsAre("depth", "depth16", "images"));
    EXPECT_EQ(npz.Header("depth").shape, (std::vector<int64_t>{2, 3, 4}));
    EXPECT_EQ(npz.Header("depth16").dtype, NpyDtype::kFloat16);
    const NpyArray d = npz.Read("depth");
    EXPECT_EQ(d.bytes, a.depth32.bytes);
    const NpyArray h = npz.ReadAsFloat32("depth16");
    ASSERT_EQ(h.dtype, NpyDtype::kFloat32);
    for (int i = 0; i < 24; ++i) EXPECT_EQ(h.Data<float>()[i], a.depth[i]);
    EXPECT_EQ(npz.Read("images").bytes, a.image.bytes);
    try {
      npz.Read("conf");
      FAIL() << "expected InputError";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("no array 'conf'"));
      EXPECT_THAT(e.what(), HasSubstr("depth, depth16, images"));
    }
  }
}

TEST(Npz, DamagedAndHostileArchivesAreInputErrors) {
  const std::string dir = test::MakeTempDir("npz_bad");
  const Arrays a;
  const std::string good = dir + "/good.npz";
  std::vector<float> big(20000, 3.0f);
  WriteZip(
      good,
      {{"depth.npy", NpyBytes(NpyArray::Float32({100, 200}, big.data()), dir)}},
      /*deflate=*/true);
  std::ifstream in(good, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  const auto write = [&](const std::string& name, const std::string& b) {
    std::ofstream(dir + "/" + name, std::ios::binary) << b;
    return dir + "/" + name;
  };
  // Not a zip at all; a zip cut in half (no central directory).
  EXPECT_THROW(NpzReader(write("text.npz", "hello")), InputError);
  EXPECT_THROW(NpzReader(write("half.npz", bytes.substr(0, bytes.size() / 2))),
               InputError);
  // A flipped byte inside the deflated data: inflate or CRC error.
  std::string flipped = bytes;
  flipped[60] = static_cast<char>(flipped[60] ^ 0x5A);
  try {
    const NpzReader npz(write("flipped.npz", flipped));
    npz.Read("depth");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("flipped.npz"));
  }
  // A member whose header declares 10^12 floats: refused from the header.
  std::vector<uint8_t> hostile = NpyBytes(a.depth32, dir);
  const std::string shape = "(2, 3, 4)";
  const std::string huge = "(1000000, 1000000)";
  std::string text(hostile.begin(), hostile.end());
  text.replace(text.find(shape), shape.size(), huge);
  WriteZip(dir + "/huge.npz",
           {{"depth.npy", std::vector<uint8_t>(text.begin(), text.end())}},
           true);
  try {
    NpzReader(dir + "/huge.npz").Read("depth");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("huge.npz: depth.npy"));
  }
}

// An archive written by NumPy itself (savez_compressed, float16 + float32).
TEST(Npz, ReadsWhatNumpyWrites) {
  GEODRIVE_REQUIRE_PYTHON_MODULE("numpy");
  const std::string dir = test::MakeTempDir("npz_numpy");
  const std::string path = dir + "/numpy.npz";
  ASSERT_EQ(
      test::RunCommand(
          std::string(test::kDebianPython) +
          " -c \"import numpy as np; d = np.arange(12, dtype=np.float32)"
          ".reshape(3, 4) / 8; np.savez_compressed('" +
          path + "', depths=d.astype(np.float16), cam_c2w=np.eye(4)[None])\""),
      0);
  const NpzReader npz(path);
  EXPECT_THAT(npz.Keys(), ::testing::ElementsAre("depths", "cam_c2w"));
  const NpyArray d = npz.ReadAsFloat32("depths");
  ASSERT_EQ(d.shape, (std::vector<int64_t>{3, 4}));
  for (int i = 0; i < 12; ++i) EXPECT_EQ(d.Data<float>()[i], i / 8.0f);
  const NpyArray c = npz.Read("cam_c2w");
  EXPECT_EQ(c.dtype, NpyDtype::kFloat64);
  EXPECT_EQ(c.shape, (std::vector<int64_t>{1, 4, 4}));
  EXPECT_EQ(c.Data<double>()[5], 1.0);
}

}  // namespace
}  // namespace geodrive
