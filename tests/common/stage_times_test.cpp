// StageTimes (common/stage_times.h): what eval, infer and serve report of where their time went.
#include <gtest/gtest.h>

#include <stdexcept>
#include <thread>
#include <vector>

#include "common/stage_times.h"

namespace ii {
namespace {

TEST(StageTimes, StagesSumTheirCallsInTheOrderTheyFirstRan) {
  StageTimes t;
  t.add("read", 2);
  t.add("render", 3);
  t.add("render", 4);
  t.add("write", 5, /*behind=*/true);
  const std::vector<StageTimes::Stage> s = t.stages();
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[0].name, "read");
  EXPECT_EQ(s[1].name, "render");
  EXPECT_DOUBLE_EQ(s[1].ms, 7);
  EXPECT_EQ(s[1].calls, 2);
  EXPECT_TRUE(s[2].behind);
  EXPECT_DOUBLE_EQ(t.ms("render"), 7);
  EXPECT_DOUBLE_EQ(t.ms("absent"), 0);
  // What the caller waited for leaves out the work behind it.
  EXPECT_DOUBLE_EQ(t.waited_ms(), 9);
  EXPECT_EQ(t.to_json(), nlohmann::json::parse(R"([{"stage": "read", "ms": 2.0, "calls": 1},
      {"stage": "render", "ms": 7.0, "calls": 2}, {"stage": "write", "ms": 5.0, "calls": 1, "behind": true}])"));
}

TEST(StageTimes, LapsAndTimedCallsMeasureWallTime) {
  StageTimes t;
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  t.restart_lap();  // the sleep belongs to no stage
  const double first = t.lap("first");
  EXPECT_LT(first, 20);
  const int value = t.time("sleep", [] {
    std::this_thread::sleep_for(std::chrono::milliseconds(15));
    return 7;
  });
  EXPECT_EQ(value, 7);
  EXPECT_GE(t.ms("sleep"), 15);
  // A call that throws still counts.
  EXPECT_THROW(t.time("throws", []() -> int { throw std::runtime_error("no"); }), std::runtime_error);
  EXPECT_EQ(t.stages().back().name, "throws");
}

TEST(StageTimes, MergeAddsAnotherCommandsStagesUnderAPrefix) {
  StageTimes prediction, job;
  prediction.add("network", 10);
  prediction.add("network", 12);
  job.add("masks: network", 1);
  job.merge(prediction, "masks: ");
  job.merge(prediction);
  const std::vector<StageTimes::Stage> s = job.stages();
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[0].name, "masks: network");
  EXPECT_DOUBLE_EQ(s[0].ms, 23);
  EXPECT_EQ(s[0].calls, 3);
  EXPECT_EQ(s[1].name, "network");
  EXPECT_EQ(s[1].calls, 2);
  const StageTimes copy = job;
  EXPECT_EQ(copy.to_json(), job.to_json());
}

TEST(StageTimes, BackgroundThreadsAddTheirOwnStages) {
  StageTimes t;
  std::vector<std::thread> writers;
  for (int w = 0; w < 4; ++w)
    writers.emplace_back([&] {
      for (int i = 0; i < 1000; ++i) t.add("write", 1, true);
    });
  for (std::thread& w : writers) w.join();
  EXPECT_EQ(t.stages().at(0).calls, 4000);
  EXPECT_DOUBLE_EQ(t.ms("write"), 4000);
}

}  // namespace
}  // namespace ii
