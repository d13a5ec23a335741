#pragma once
// Test helpers shared by all module test suites.

#include <gmock/gmock.h>

#include <Eigen/Core>
#include <cstdint>
#include <cstdlib>
#include <functional>
#include <random>
#include <string>

namespace geodrive {
namespace test {

// The seed every test starts from (reset before each test by the shared main).
constexpr uint32_t kTestSeed = 20250528;
// A generator re-seeded with kTestSeed before every test.
std::mt19937& Rng();

// A fresh empty temporary directory for this test process:
// test_tmp/<name>-<pid> under the build tree. Unique per process, so
// `ctest -j` runs cannot collide. The shared main removes it at exit when
// every test of the process passed (RemoveTempDirs) and keeps it for a
// failure, or always with GEODRIVE_KEEP_TEST_TMP=1.
std::string MakeTempDir(const std::string& name);
// Removes every directory MakeTempDir made in this process (errors ignored:
// a test may have removed its own) and returns their count. A whole test run
// leaves ≈ 5 GB otherwise, which filled a small CI disk.
int RemoveTempDirs();

// A directory shared by every test process of this build
// (test_tmp/shared/<name>): the first caller runs `build(dir)` under an
// exclusive file lock and marks it complete; later callers (in this or other
// processes, e.g. under `ctest -j`) wait for the lock and reuse it. A rebuilt
// test binary rebuilds the fixture.
std::string SharedFixtureDir(
    const std::string& name,
    const std::function<void(const std::string&)>& build);

// The whole file as bytes ("" when it cannot be opened).
std::string ReadFile(const std::string& path);
// Writes `bytes` as the whole file (binary; no error check: tests that need
// one check the file afterwards).
void WriteFile(const std::string& path, const std::string& bytes);

// The number of '\n' in `text`.
int CountLines(const std::string& text);

// Path to ../shared/data/real/<relative>.
std::string RealDataPath(const std::string& relative);
// Path of the built `geodrive` binary.
std::string GeodriveBinary();
// Runs a shell command, returns its exit code; captures stdout+stderr into
// *output if non-null.
int RunCommand(const std::string& command, std::string* output = nullptr);
// Runs `geodrive eval <args>`; returns its combined output, its exit code in
// *rc.
std::string RunGeodriveEval(const std::string& args, int* rc);
// The interpreter that sees Debian's python3-* packages.
constexpr const char* kDebianPython = "/usr/bin/python3";
// True if `/usr/bin/python3 -c "import <module>"` succeeds.
bool PythonHasModule(const std::string& module);

// GMock matcher: two Eigen matrices of equal shape agree elementwise within
// `tol`.
MATCHER_P2(EigenNear, expected, tol, "") {
  if (arg.rows() != expected.rows() || arg.cols() != expected.cols())
    return false;
  const double err = (arg - expected).cwiseAbs().maxCoeff();
  *result_listener << "max abs difference " << err;
  return err <= tol;
}

}  // namespace test
}  // namespace geodrive

// Skips the current test with a visible message when Debian's python lacks
// `module`, unless the environment sets GEODRIVE_REQUIRE_PYTHON_CHECKS=1 (CI),
// in which case the test fails instead.
#define GEODRIVE_REQUIRE_PYTHON_MODULE(module)                        \
  do {                                                                \
    if (!::geodrive::test::PythonHasModule(module)) {                 \
      if (std::getenv("GEODRIVE_REQUIRE_PYTHON_CHECKS") != nullptr) { \
        FAIL() << "python module '" << module                         \
               << "' missing and GEODRIVE_REQUIRE_PYTHON_CHECKS "     \
                  "is set";                                           \
      }                                                               \
      GTEST_SKIP() << "SKIPPED: /usr/bin/python3 has no '" << module  \
                   << "' (install python3-" << module                 \
                   << " to run this cross-check)";                    \
    }                                                                 \
  } while (0)
