// Paths that are not regular files (geometry/util/input_file.h): a FIFO with
// no writer, folders named like inputs, /dev/zero, /dev/null, a socket,
// symbolic links to those and a dangling one, given to every kind of reader
// (trajectories, JSON, intrinsics, arrays, point clouds, images, EXR). Each
// call must end within seconds with one InputError naming the path and what it
// is; a reader that blocks or reads without end fails the test instead of
// hanging it.

#include "geometry/util/input_file.h"

#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <future>
#include <string>
#include <vector>

#include "geometry/exr.h"
#include "geometry/image_io.h"
#include "geometry/npy.h"
#include "geometry/npz.h"
#include "geometry/point_cloud_io.h"
#include "geometry/pointmap.h"
#include "geometry/trajectory_io.h"
#include "geometry/trajectory_json.h"
#include "geometry/util/files.h"
#include "geometry/util/status.h"
#include "tests/common/test_util.h"

namespace geodrive {
// A named namespace, not an anonymous one: the unity build compiles this
// file with others of its folder, whose anonymous helpers share names.
namespace input_file_test {

namespace fs = std::filesystem;

// One reader of a path, by name.
struct Reader {
  std::string name;
  std::function<void(const std::string&)> read;
};

std::vector<Reader> Readers() {
  return {
      {"OpenInputFile", [](const std::string& p) { OpenInputFile(p); }},
      {"InputFileStream", [](const std::string& p) { InputFileStream in(p); }},
      {"ReadFileText", [](const std::string& p) { ReadFileText(p); }},
      {"ReadTumTrajectory", [](const std::string& p) { ReadTumTrajectory(p); }},
      {"ReadKittiTrajectory",
       [](const std::string& p) { ReadKittiTrajectory(p); }},
      {"ReadColmapTrajectory",
       [](const std::string& p) { ReadColmapTrajectory(p); }},
      {"ReadMonst3rTrajectory",
       [](const std::string& p) { ReadMonst3rTrajectory(p); }},
      {"ReadTrajectoryJson",
       [](const std::string& p) { ReadTrajectoryJson(p); }},
      {"ReadIntrinsicsFile",
       [](const std::string& p) { ReadIntrinsicsFile(p, 64, 48); }},
      {"ReadNpy", [](const std::string& p) { ReadNpy(p); }},
      {"ReadNpyHeader", [](const std::string& p) { ReadNpyHeader(p); }},
      {"NpzReader", [](const std::string& p) { NpzReader npz(p); }},
      {"ReadPly", [](const std::string& p) { ReadPly(p); }},
      {"ReadPcd", [](const std::string& p) { ReadPcd(p); }},
      {"ReadNuscenesLidarBin",
       [](const std::string& p) { ReadNuscenesLidarBin(p); }},
      {"ReadImageRgb", [](const std::string& p) { ReadImageRgb(p); }},
      {"ReadImageHeader", [](const std::string& p) { ReadImageHeader(p); }},
      {"ExrChannels", [](const std::string& p) { ExrChannels(p); }},
  };
}

// The message of the InputError `read(path)` throws; fails the test for any
// other outcome, and ends the process (instead of hanging) when the call does
// not return within a few seconds.
std::string ErrorOf(const Reader& reader, const std::string& path) {
  auto call = std::async(std::launch::async, [&]() -> std::string {
    try {
      reader.read(path);
    } catch (const InputError& e) {
      return e.what();
    } catch (const std::exception& e) {
      return std::string("not an InputError: ") + e.what();
    }
    return "no error";
  });
  if (call.wait_for(std::chrono::seconds(5)) != std::future_status::ready) {
    std::fprintf(stderr, "%s(%s) did not return within 5 s\n",
                 reader.name.c_str(), path.c_str());
    std::fflush(stderr);
    std::_Exit(1);  // the blocked thread cannot be joined
  }
  return call.get();
}

// A path and what the error must say about it.
struct Hostile {
  std::string path;
  std::string kind;
};

class NotRegularFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::MakeTempDir("input_file");
    const std::string fifo = dir_ + "/traj.fifo";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    for (const char* name : {"x.json", "traj.txt", "cloud.ply"})
      fs::create_directory(dir_ + "/" + name);
    fs::create_symlink(fifo, dir_ + "/link_to_fifo.npy");
    fs::create_symlink("/dev/zero", dir_ + "/zero.ply");
    fs::create_symlink(dir_ + "/absent.txt", dir_ + "/dangling.txt");
    // A listening Unix socket (open() of it fails with ENXIO).
    const std::string socket_path = dir_ + "/sock.json";
    socket_ = ::socket(AF_UNIX, SOCK_STREAM, 0);
    ASSERT_GE(socket_, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    ASSERT_LT(socket_path.size(), sizeof(addr.sun_path));
    std::snprintf(addr.sun_path, sizeof(addr.sun_path), "%s",
                  socket_path.c_str());
    ASSERT_EQ(::bind(socket_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)),
              0);
    const std::string fifo_kind = "is a FIFO/pipe, not a regular file";
    const std::string dir_kind = "is a directory (expected a file)";
    const std::string char_kind = "is a character device, not a regular file";
    hostile_ = {
        {fifo, fifo_kind},
        {dir_ + "/link_to_fifo.npy", fifo_kind},
        {dir_ + "/x.json", dir_kind},
        {dir_ + "/traj.txt", dir_kind},
        {dir_ + "/cloud.ply", dir_kind},
        {"/dev/zero", char_kind},
        {"/dev/null", char_kind},
        {dir_ + "/zero.ply", char_kind},
        {socket_path, "is a socket, not a regular file"},
        {dir_ + "/dangling.txt", "cannot open (No such file or directory)"},
    };
  }
  void TearDown() override {
    if (socket_ >= 0) ::close(socket_);
  }

  std::string dir_;
  int socket_ = -1;
  std::vector<Hostile> hostile_;
};

TEST_F(NotRegularFiles, EveryReaderRefusesWithOneLineNamingThePathAndKind) {
  const std::vector<Reader> readers = Readers();
  ASSERT_GE(readers.size(), 5u);
  for (const Reader& reader : readers) {
    for (const Hostile& h : hostile_) {
      SCOPED_TRACE(reader.name + "(" + h.path + ")");
      const std::string error = ErrorOf(reader, h.path);
      EXPECT_EQ(error, h.path + ": " + h.kind);
    }
  }
}

TEST_F(NotRegularFiles, ZipSniffingSaysNoWithoutBlocking) {
  for (const Hostile& h : hostile_) {
    auto call =
        std::async(std::launch::async, [&] { return LooksLikeZip(h.path); });
    ASSERT_EQ(call.wait_for(std::chrono::seconds(5)), std::future_status::ready)
        << h.path;
    EXPECT_FALSE(call.get()) << h.path;
  }
}

TEST(InputFile, RegularFilesReadAsBefore) {
  const std::string dir = test::MakeTempDir("input_file_regular");
  const std::string path = dir + "/a.txt";
  const std::string text = std::string("line one\nline two\0binary", 24);
  WriteFileAtomic(path, text);
  EXPECT_EQ(ReadFileText(path), text);
  EXPECT_EQ(ReadInputFileText(path, 1 << 20), text);
  EXPECT_EQ(FileSizeOrThrow(path), text.size());
  EXPECT_EQ(CheckInputFile(path), text.size());
  InputFileStream in(path, 4);  // a buffer smaller than the file
  EXPECT_EQ(in.size(), text.size());
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_EQ(line, "line one");
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_EQ(line, std::string("line two\0binary", 15));
  const std::string empty = dir + "/empty.txt";
  WriteFileAtomic(empty, "");
  EXPECT_EQ(ReadFileText(empty), "");
  // A symbolic link to a regular file is followed.
  fs::create_symlink(path, dir + "/link.txt");
  EXPECT_EQ(ReadFileText(dir + "/link.txt"), text);
}

TEST(InputFile, SizeCapNamesThePath) {
  const std::string dir = test::MakeTempDir("input_file_cap");
  const std::string path = dir + "/big.txt";
  WriteFileAtomic(path, std::string(100, 'x'));
  try {
    ReadInputFileBytes(path, 10);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              path + ": file of 100 bytes exceeds the limit of 10 bytes");
  }
}

TEST(InputFile, ReleasedDescriptorStaysOpen) {
  const std::string dir = test::MakeTempDir("input_file_release");
  const std::string path = dir + "/a.bin";
  WriteFileAtomic(path, "abc");
  InputFile file = OpenInputFile(path);
  EXPECT_EQ(file.size(), 3u);
  EXPECT_EQ(file.path(), path);
  // Blocking mode is restored after the check.
  EXPECT_EQ(::fcntl(file.fd(), F_GETFL) & O_NONBLOCK, 0);
  const int fd = file.Release();
  EXPECT_EQ(file.fd(), -1);
  char buf[3];
  EXPECT_EQ(::read(fd, buf, 3), 3);
  ::close(fd);
}

}  // namespace input_file_test
}  // namespace geodrive
