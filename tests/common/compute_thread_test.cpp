// The thread every LibTorch work of a server runs on (common/compute_thread.h).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>

#include "common/compute_thread.h"

namespace ii {
namespace {

TEST(ComputeThread, RunsOnItsOwnThreadAndGivesTheResultBack) {
  ComputeThread compute;
  EXPECT_FALSE(compute.on_this_thread());
  std::thread::id ran_on;
  EXPECT_EQ(compute.run([&] {
              ran_on = std::this_thread::get_id();
              return 42;
            }),
            42);
  EXPECT_NE(ran_on, std::this_thread::get_id());
  // From the compute thread itself: at once (no wait behind itself).
  EXPECT_EQ(compute.run([&] { return compute.run([&] { return compute.on_this_thread() ? 7 : 0; }); }), 7);
}

TEST(ComputeThread, AnExceptionReachesTheCaller) {
  ComputeThread compute;
  EXPECT_THROW(compute.run([]() -> int { throw std::runtime_error("no"); }), std::runtime_error);
  EXPECT_EQ(compute.run([] { return 1; }), 1);  // and the thread goes on
}

TEST(ComputeThread, WhileItWorksRunIfIdleRunsOnTheCaller) {
  ComputeThread compute;
  std::atomic<bool> started{false}, release{false};
  std::thread long_job([&] {
    compute.run([&] {
      started = true;
      while (!release) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    });
  });
  while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_TRUE(compute.busy());
  EXPECT_EQ(compute.run_if_idle([] { return std::this_thread::get_id(); }), std::this_thread::get_id());
  release = true;
  long_job.join();
  EXPECT_FALSE(compute.busy());
  EXPECT_NE(compute.run_if_idle([] { return std::this_thread::get_id(); }), std::this_thread::get_id());
}

TEST(ComputeThread, EndsAfterWhatWasPosted) {
  std::atomic<int> done{0};
  std::thread caller;
  {
    ComputeThread compute;
    caller = std::thread([&] { compute.run([&] {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      ++done;
    }); });
    while (!compute.busy()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  caller.join();
  EXPECT_EQ(done, 1);
}

}  // namespace
}  // namespace ii
