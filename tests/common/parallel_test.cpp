// The thread plan every command shares (common/parallel.h) and the helpers that spread work.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
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

TEST(Parallel, RangesCoverEachItemOnceAndNestedCallsRunOnTheirCaller) {
  for (const int64_t n : {7, 1000, 1001}) {  // (one item: no team, and a nested call may have one)
    std::vector<std::atomic<int>> seen(static_cast<size_t>(n));
    std::atomic<int> nested_threads_seen{0};
    parallel_range(n, 1, 3, [&](int64_t b, int64_t e) {
      const std::thread::id outer = std::this_thread::get_id();
      for (int64_t i = b; i < e; ++i) ++seen[static_cast<size_t>(i)];
      parallel_dynamic(4, 4, [&](int64_t) {
        if (std::this_thread::get_id() != outer) ++nested_threads_seen;
      });
    });
    for (const auto& s : seen) EXPECT_EQ(s.load(), 1) << n;
    EXPECT_EQ(nested_threads_seen.load(), 0) << "a nested call runs serially on its caller";
  }
}

// With OpenMP the work runs on its team, LibTorch's: the same worker threads call after call,
// never a second pool beside the one that waits after each LibTorch operation. (Kernel thread
// ids: a new thread gets a new one, where a std::thread::id may be reused after a join.)
TEST(Parallel, WithOpenMpTheWorkersAreOneTeamCallAfterCall) {
  if (!parallel_on_openmp()) GTEST_SKIP() << "built without OpenMP (the sanitizer build): threads per call";
  auto workers = [] {
    const pid_t caller = gettid();
    std::mutex m;
    std::set<pid_t> ids;
    parallel_range(2, 1, 2, [&](int64_t, int64_t) {  // one item each for a team of 2
      const std::lock_guard<std::mutex> lock(m);
      if (gettid() != caller) ids.insert(gettid());
    });
    return ids;
  };
  const std::set<pid_t> first = workers();
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(workers(), first);
}

}  // namespace
}  // namespace ii
