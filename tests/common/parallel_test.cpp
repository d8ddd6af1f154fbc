// The thread plan every command shares (common/parallel.h) and the helpers that spread work.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "common/parallel.h"

namespace ii {
namespace {

TEST(ThreadPlan, CpuRunsGiveLibTorchEveryCoreGpuRunsHalf) {
  const ThreadPlan cpu = plan_threads(16, false), gpu = plan_threads(16, true);
  EXPECT_EQ(cpu.cores, 16);
  EXPECT_EQ(cpu.compute, 16);
  EXPECT_EQ(cpu.files, 4);
  EXPECT_EQ(gpu.compute, 8);
  EXPECT_EQ(gpu.files, 4);
  // Busy threads never outnumber the cores on a GPU run: LibTorch, decoding, writing.
  EXPECT_LE(gpu.compute + 2 * gpu.files, gpu.cores);
  const ThreadPlan small = plan_threads(2, true);
  EXPECT_EQ(small.compute, 1);
  EXPECT_EQ(small.files, 1);
  EXPECT_EQ(plan_threads(1, false).files, 1);
}

TEST(ThreadPlan, WithoutARequestOmpNumThreadsThenEveryCore) {
  const char* saved = std::getenv("OMP_NUM_THREADS");
  const std::string restore = saved ? saved : "";
  setenv("OMP_NUM_THREADS", "6", 1);
  EXPECT_EQ(plan_threads(0, false).cores, 6);
  EXPECT_EQ(plan_threads(3, false).cores, 3);  // a request wins
  unsetenv("OMP_NUM_THREADS");
  EXPECT_GE(plan_threads(0, false).cores, 1);
  if (saved) setenv("OMP_NUM_THREADS", restore.c_str(), 1);
  const ThreadPlan before = thread_plan();
  set_thread_plan(plan_threads(5, true));
  EXPECT_EQ(thread_plan().cores, 5);
  set_thread_plan(before);
}

TEST(Parallel, EveryItemOnceAndTheFirstFailureRethrown) {
  std::vector<std::atomic<int>> seen(1000);
  parallel_dynamic(1000, 4, [&](int64_t i) { ++seen[static_cast<size_t>(i)]; });
  for (const auto& s : seen) EXPECT_EQ(s.load(), 1);
  EXPECT_THROW(parallel_range(100, 1, 4, [](int64_t b, int64_t) {
                 if (b == 0) throw std::runtime_error("first chunk");
               }),
               std::runtime_error);
}

}  // namespace
}  // namespace ii
