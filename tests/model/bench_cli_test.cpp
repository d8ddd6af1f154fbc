// `instainpaint bench` end to end: sizes, baselines and the refusals, on the tiny preset
// (runs the built executable; skipped when it has not been built).
#include <gtest/gtest.h>

#include <fmt/core.h>
#include "common/torch.h"

#include "common/files.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

struct BenchRun {
  int code = 0;
  std::string output;
};

BenchRun bench(const fs::path& exe, const std::string& args) {
  const fs::path log = test::temp_dir("bench-cli") / "log.txt";
  BenchRun r;
  r.code = test::run_command(fmt::format("'{}' bench --presets tiny --threads 1 {}", exe.string(), args), log);
  r.output = read_file_text(log);
  return r;
}

TEST(BenchCli, TimesEachSizeAgainstTheChosenBaseline) {
  II_REQUIRE_CLI(exe);
  const BenchRun official = bench(exe, "--sizes 32,48x16 --repeat 1 --baseline official --precision fp32 --device cpu");
  ASSERT_EQ(official.code, 0) << official.output;
  // One row per size (width x height), tokens = views x (W/8) x (H/8), a ratio to the baseline.
  EXPECT_NE(official.output.find("tiny         32x32      64"), std::string::npos) << official.output;
  EXPECT_NE(official.output.find("tiny         48x16      48"), std::string::npos) << official.output;
  EXPECT_NE(official.output.find("baseline: the official code's way of computing"), std::string::npos);
  EXPECT_EQ(official.output.find("graph ms"), std::string::npos);  // CUDA graphs: GPU only

  const BenchRun none = bench(exe, "--sizes 16 --baseline none");
  ASSERT_EQ(none.code, 0) << none.output;
  EXPECT_NE(none.output.find("tiny         16x16"), std::string::npos) << none.output;
  EXPECT_EQ(none.output.find("baseline:"), std::string::npos) << none.output;
}

TEST(BenchCli, RefusesWhatItCannotMeasure) {
  II_REQUIRE_CLI(exe);
  EXPECT_EQ(bench(exe, "--sizes 63x").output,
            "error: --sizes: '63x' is not a size (expected N for N x N, or WIDTHxHEIGHT)\n");
  EXPECT_EQ(bench(exe, "--sizes 36").output, "error: --sizes: 36x36 is not a multiple of the tiny model's patch size 8\n");
  EXPECT_EQ(bench(exe, "--sizes 4x8").output, "error: --sizes: 4x8 is outside 8..8192 pixels\n");
  if (!torch::cuda::is_available()) {
    const BenchRun cuda = bench(exe, "--device cuda");
    EXPECT_NE(cuda.code, 0);
    EXPECT_EQ(cuda.output,
              "error: --device cuda: no CUDA device is available to LibTorch (a CPU-only build, or no GPU/driver "
              "visible)\n");
  }
}

}  // namespace
}  // namespace ii
