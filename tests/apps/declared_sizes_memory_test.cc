// Every reader given a small file that declares a huge size stays under
// 200 MB resident (geometry/util/size_limits.h, docs/RELIABILITY.md "Sizes
// checked before allocating"). Each reader runs in a forked child on its
// hostile file; the child must end with the reader's InputError and its peak
// resident set (wait4's ru_maxrss) must stay under the bound: npz, npy, EXR
// (a huge window, huge tiles), PLY, PCD, a nuScenes JSON table, a video, and
// (through `geodrive-diffusion check-weights`) a safetensors checkpoint.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <functional>

#include "dataset/nuscenes.h"
#include "geometry/exr.h"
#include "geometry/npy.h"
#include "geometry/npz.h"
#include "geometry/point_cloud_io.h"
#include "geometry/util/status.h"
#include "render/video/video_io.h"
#include "tests/common/test_util.h"

namespace geodrive {
// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder, whose anonymous helpers share names.
namespace declared_sizes_memory_test {

constexpr long kBoundKb = 200 * 1024;

void Put32(std::string* s, size_t at, uint32_t v) {
  for (int k = 0; k < 4; ++k) (*s)[at + k] = static_cast<char>(v >> (8 * k));
}

std::string Le32(int32_t v) {
  std::string s(4, '\0');
  Put32(&s, 0, static_cast<uint32_t>(v));
  return s;
}

// Runs `read` in a child; returns its peak RSS in KB, and whether it ended
// with an InputError (exit 2) in `input_error`.
long PeakRssKb(const std::function<void()>& read, bool* input_error) {
  const pid_t pid = fork();
  if (pid == 0) {
    int code = 0;
    try {
      read();
    } catch (const InputError& e) {
      std::fprintf(stderr, "  %s\n", e.what());
      code = 2;
    } catch (...) {
      code = 3;
    }
    std::fflush(stderr);
    _exit(code);
  }
  int status = 0;
  rusage usage{};
  EXPECT_EQ(wait4(pid, &status, 0, &usage), pid);
  *input_error = WIFEXITED(status) && WEXITSTATUS(status) == 2;
  return usage.ru_maxrss;
}

// Runs `command` in a child (a shell); its peak RSS in KB and exit code.
long PeakRssKbOfCommand(const std::string& command, int* code) {
  const pid_t pid = fork();
  if (pid == 0) {
    execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  int status = 0;
  rusage usage{};
  EXPECT_EQ(wait4(pid, &status, 0, &usage), pid);
  *code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return usage.ru_maxrss;
}

TEST(DeclaredSizesMemory, EveryReaderStaysUnder200MbOnAHugeDeclaredSize) {
  const std::string dir = test::MakeTempDir("declared_sizes_memory");
  std::vector<std::pair<std::string, std::function<void()>>> cases;

  // npz: a member declaring 3 GiB in a few hundred bytes.
  {
    std::vector<float> v(100, 1.f);
    WriteNpz(dir + "/good.npz",
             {{"depth", NpyArray::Float32({100}, v.data())}});
    std::string zip = test::ReadFile(dir + "/good.npz");
    for (size_t at = zip.find("PK\x03\x04"); at != std::string::npos;
         at = zip.find("PK\x03\x04", at + 4))
      Put32(&zip, at + 22, 3u << 30);
    for (size_t at = zip.find("PK\x01\x02"); at != std::string::npos;
         at = zip.find("PK\x01\x02", at + 4))
      Put32(&zip, at + 24, 3u << 30);
    test::WriteFile(dir + "/huge.npz", zip);
    cases.push_back(
        {"npz", [&] { NpzReader(dir + "/huge.npz").Read("depth"); }});
  }
  // npy: a header declaring 10^10 floats over 1 KB of data.
  {
    std::vector<float> v(256, 1.f);
    WriteNpy(dir + "/good.npy", NpyArray::Float32({256}, v.data()));
    std::string npy = test::ReadFile(dir + "/good.npy");
    npy.replace(npy.find("(256,)"), 6, "(100000, 100000)");
    test::WriteFile(dir + "/huge.npy", npy);
    cases.push_back({"npy", [&] { ReadNpy(dir + "/huge.npy"); }});
  }
  // EXR: 16384 x 16384 uncompressed, only the offset table (131 KB).
  {
    const auto attr = [](const std::string& n, const std::string& t,
                         const std::string& v) {
      return n + '\0' + t + '\0' + Le32(static_cast<int32_t>(v.size())) + v;
    };
    const std::string box = Le32(0) + Le32(0) + Le32(16383) + Le32(16383);
    std::string exr =
        Le32(20000630) + Le32(2) +
        attr("channels", "chlist",
             std::string("Z") + '\0' + Le32(2) + std::string(4, '\0') +
                 Le32(1) + Le32(1) + '\0') +
        attr("compression", "compression", std::string(1, 0)) +
        attr("dataWindow", "box2i", box) + attr("displayWindow", "box2i", box) +
        '\0';
    exr += std::string(16384 * 8, '\0');
    test::WriteFile(dir + "/huge.exr", exr);
    cases.push_back({"EXR", [&] { ReadExr(dir + "/huge.exr", {"Z"}); }});
    // Tiles of 1 x 469762048 over a 4 x 4 window (fuzz_exr_header's third
    // finding: OpenEXR sized its tile buffer, 1.88 GB, by the tile).
    const std::string small = Le32(0) + Le32(0) + Le32(3) + Le32(3);
    std::string tiled =
        Le32(20000630) + Le32(2 | 0x200) +
        attr("channels", "chlist",
             std::string("Z") + '\0' + Le32(2) + std::string(4, '\0') +
                 Le32(1) + Le32(1) + '\0') +
        attr("compression", "compression", std::string(1, 0)) +
        attr("dataWindow", "box2i", small) +
        attr("displayWindow", "box2i", small) +
        attr("tiles", "tiledesc",
             Le32(1) + Le32(469762048) + std::string(1, 0)) +
        '\0' + std::string(64, '\0');
    test::WriteFile(dir + "/tall_tiles.exr", tiled);
    cases.push_back(
        {"EXR tiles", [&] { ReadExr(dir + "/tall_tiles.exr", {"Z"}); }});
  }
  // PLY and PCD: 50 million points declared over 64 KB.
  {
    test::WriteFile(dir + "/huge.ply",
                    "ply\nformat binary_little_endian 1.0\nelement vertex "
                    "50000000\nproperty float x\nproperty float y\nproperty "
                    "float z\nend_header\n" +
                        std::string(65536, '\0'));
    cases.push_back({"PLY", [&] { ReadPly(dir + "/huge.ply"); }});
    test::WriteFile(dir + "/huge.pcd",
                    "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT "
                    "1 1 1\nWIDTH 50000000\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 "
                    "0\nPOINTS 50000000\nDATA binary\n" +
                        std::string(65536, '\0'));
    cases.push_back({"PCD", [&] { ReadPcd(dir + "/huge.pcd"); }});
  }
  // A nuScenes table: a million nested arrays in 2 MB (the depth limit).
  {
    const std::string root = dir + "/nuscenes";
    std::filesystem::create_directories(root + "/v1.0-mini");
    for (const char* t :
         {"attribute", "calibrated_sensor", "category", "ego_pose", "instance",
          "log", "map", "sample", "sample_annotation", "sample_data", "scene",
          "sensor", "visibility"})
      test::WriteFile(root + "/v1.0-mini/" + t + ".json", "[]");
    test::WriteFile(root + "/v1.0-mini/sample_data.json",
                    std::string(1000000, '[') + std::string(1000000, ']'));
    cases.push_back({"JSON table", [root] {
                       NuscenesOptions o;
                       o.dataroot = root;
                       o.num_threads = 1;
                       Nuscenes nusc(o);
                     }});
  }
  // Video: an AVI declaring a million frames.
  {
    std::vector<cv::Mat> frames(2, cv::Mat(16, 16, CV_8UC3, cv::Scalar(90)));
    WriteVideoFrames(dir + "/small.avi", frames, 10);
    std::string avi = test::ReadFile(dir + "/small.avi");
    Put32(&avi, avi.find("avih") + 8 + 16, 1000000);
    Put32(&avi, avi.find("strh") + 8 + 32, 1000000);
    test::WriteFile(dir + "/million.avi", avi);
    cases.push_back({"video", [&] { ReadVideoFrames(dir + "/million.avi"); }});
  }

  for (const auto& [name, read] : cases) {
    bool input_error = false;
    const long kb = PeakRssKb(read, &input_error);
    std::cout << name << ": peak " << kb / 1024 << " MB resident\n";
    EXPECT_TRUE(input_error) << name << " did not end with an InputError";
    EXPECT_LT(kb, kBoundKb) << name;
  }

  // safetensors: a header length field of 2^60, through the LibTorch binary.
  const std::string diffusion =
      std::string(GEODRIVE_BINARY_DIR) + "/diffusion/geodrive-diffusion";
  if (std::filesystem::exists(diffusion)) {
    std::string st(8, '\0');
    st[7] = 0x10;  // 2^60, little-endian
    test::WriteFile(dir + "/huge.safetensors", st + "{}");
    int code = 0;
    const long kb = PeakRssKbOfCommand(
        "exec " + diffusion + " check-weights --weights " + dir +
            "/huge.safetensors > " + dir + "/safetensors.txt 2>&1",
        &code);
    std::cout << "safetensors (geodrive-diffusion, exit " << code << "): peak "
              << kb / 1024 << " MB resident, "
              << test::ReadFile(dir + "/safetensors.txt");
    EXPECT_EQ(code, 2);
    EXPECT_LT(kb, kBoundKb);
  }
}

}  // namespace declared_sizes_memory_test
}  // namespace geodrive
