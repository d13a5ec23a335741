// Shared GoogleTest main: initialises glog and re-seeds all test randomness before every test,
// so randomised tests are deterministic and independent of execution order.

#include <glog/logging.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "tests/common/test_util.h"

namespace {
class SeedListener : public ::testing::EmptyTestEventListener {
  void OnTestStart(const ::testing::TestInfo&) override {
    geodrive::test::Rng().seed(geodrive::test::kTestSeed);
    std::srand(geodrive::test::kTestSeed);
  }
};
}  // namespace

int main(int argc, char** argv) {
  google::InitGoogleLogging(argv[0]);
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = 1;
  ::testing::InitGoogleTest(&argc, argv);
  ::testing::UnitTest::GetInstance()->listeners().Append(new SeedListener);
  const int rc = RUN_ALL_TESTS();
  // Every test passed: its temporary folders go (a failure keeps them to look
  // at). Shared fixtures (SharedFixtureDir) stay for the other test processes.
  const char* keep = std::getenv("GEODRIVE_KEEP_TEST_TMP");
  if (rc == 0 && !(keep && std::string(keep) == "1"))
    geodrive::test::RemoveTempDirs();
  return rc;
}
