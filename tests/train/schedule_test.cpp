// Learning-rate schedule (spec §6.5): warm-up endpoints, cosine values, option errors.
#include <gtest/gtest.h>

#include <cmath>

#include "test_support.h"
#include "train/schedule.h"

namespace ii {
namespace {

LrSchedule official(int64_t total) {
  LrSchedule s;  // defaults: 1e-10 -> 8e-5 over 200 iterations, cosine to 1e-6
  s.total_steps = total;
  return s;
}

TEST(LrSchedule, WarmupHitsBothEndpoints) {
  const LrSchedule s = official(1200);
  EXPECT_DOUBLE_EQ(s.at(0), 1e-10);
  EXPECT_DOUBLE_EQ(s.at(199), 8e-5);
  EXPECT_DOUBLE_EQ(s.at(100), 1e-10 + (8e-5 - 1e-10) * 100.0 / 199.0);
  for (int64_t k = 1; k < 200; ++k) EXPECT_GT(s.at(k), s.at(k - 1));
}

TEST(LrSchedule, CosineFromPeakToFinal) {
  const LrSchedule s = official(1200);  // 1000 decay iterations
  EXPECT_DOUBLE_EQ(s.at(200), 8e-5);    // k = 0 of the cosine
  EXPECT_DOUBLE_EQ(s.at(700), 1e-6 + 0.5 * (8e-5 - 1e-6));
  EXPECT_DOUBLE_EQ(s.at(450), 1e-6 + 0.5 * (8e-5 - 1e-6) * (1 + std::cos(M_PI * 0.25)));
  EXPECT_DOUBLE_EQ(s.at(1200), 1e-6);
  EXPECT_DOUBLE_EQ(s.at(5000), 1e-6);
  for (int64_t k = 201; k < 1200; ++k) EXPECT_LT(s.at(k), s.at(k - 1));
}

TEST(LrSchedule, NoWarmup) {
  LrSchedule s = official(10);
  s.warmup_steps = 0;
  EXPECT_DOUBLE_EQ(s.at(0), 8e-5);
  EXPECT_DOUBLE_EQ(s.at(5), 1e-6 + 0.5 * (8e-5 - 1e-6));
}

TEST(LrSchedule, RejectsBadOptions) {
  EXPECT_EQ(test::error_message([] { official(200).validate(); }),
            "--warmup must be between 0 and --steps - 1 (199), got 200");
  EXPECT_EQ(test::error_message([] { official(0).validate(); }), "--steps must be at least 1, got 0");
  LrSchedule s = official(1000);
  s.peak_lr = -1;
  EXPECT_EQ(test::error_message([&] { s.validate(); }), "--lr must be a positive number, got -1");
}

}  // namespace
}  // namespace ii
