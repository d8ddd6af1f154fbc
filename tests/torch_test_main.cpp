// The main() of the tests that use LibTorch. LibTorch seeds its default generator from the
// operating system when a process starts, so a test that drew random numbers before seeding
// saw different numbers in every run (and passed or failed by chance). Every test now starts
// from the same seed, whatever it forgets and whichever tests ran before it in the process.
#include <gtest/gtest.h>
#include "common/torch.h"

namespace {
class SeedEveryTest : public ::testing::EmptyTestEventListener {
  void OnTestStart(const ::testing::TestInfo&) override { torch::manual_seed(0); }
};
}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ::testing::UnitTest::GetInstance()->listeners().Append(new SeedEveryTest);
  return RUN_ALL_TESTS();
}
