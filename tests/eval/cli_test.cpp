// `instainpaint metrics` and `instainpaint eval` end to end: runs the built executable
// (beside the tests' folder); skipped when it has not been built.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "common/files.h"
#include "io/image.h"
#include "synthetic_scene.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// Runs the command without the metric-weight environment variables; returns the exit code.
int run(const std::string& args, const fs::path& log) {
  return test::run_command("env -u INSTAINPAINT_LPIPS_VGG -u INSTAINPAINT_LPIPS_ALEX -u INSTAINPAINT_FID_INCEPTION " + args,
                           log);
}

TEST(MetricsCli, JsonOfAPair) {
  II_REQUIRE_CLI(exe);
  const fs::path dir = test::temp_dir("metrics-cli");
  Image a(32, 24, 3, 0.2f), b(32, 24, 3, 0.2f), mask(32, 24, 1, 0.f);
  for (int y = 4; y < 12; ++y)
    for (int x = 8; x < 16; ++x) {
      mask.at(y, x) = 1;
      for (int c = 0; c < 3; ++c) b.at(y, x, c) = 0.6f;  // 0.4 error on the 64 mask pixels only
    }
  write_png(dir / "a.png", a);
  write_png(dir / "b.png", b);
  write_png(dir / "mask.png", mask);
  ASSERT_EQ(run(fmt::format("'{}' metrics '{}' '{}' --mask '{}' --json", exe.string(), (dir / "a.png").string(),
                            (dir / "b.png").string(), (dir / "mask.png").string()),
                dir / "out.json"),
            0)
      << read_file_text(dir / "out.json");
  const json m = json::parse(read_file_text(dir / "out.json"));
  // 8-bit values: 0.2 -> 51/255, 0.6 -> 153/255, a difference of exactly 0.4.
  EXPECT_NEAR(m["masked_psnr"].get<double>(), -10 * std::log10(0.16), 1e-4);
  EXPECT_NEAR(m["box_psnr"].get<double>(), -10 * std::log10(0.16), 1e-4);
  EXPECT_NEAR(m["psnr"].get<double>(), -10 * std::log10(0.16 * 64 / 768), 1e-4);
  EXPECT_EQ(m["mask_pixels"], 64);
  EXPECT_TRUE(m["unavailable"]["lpips"].get<std::string>().rfind("LPIPS-vgg needs", 0) == 0);

  // Identical images: "inf"; text output names unavailable metrics.
  ASSERT_EQ(run(fmt::format("'{}' metrics '{}' '{}'", exe.string(), (dir / "a.png").string(), (dir / "a.png").string()),
                dir / "out.txt"),
            0);
  const std::string text = read_file_text(dir / "out.txt");
  EXPECT_NE(text.find("psnr          inf"), std::string::npos) << text;
  EXPECT_NE(text.find("lpips         unavailable: LPIPS-vgg needs"), std::string::npos) << text;

  // Different sizes: exit 1 with the files named.
  write_png(dir / "small.png", Image(16, 24, 3));
  EXPECT_EQ(
      run(fmt::format("'{}' metrics '{}' '{}'", exe.string(), (dir / "a.png").string(), (dir / "small.png").string()),
          dir / "err.txt"),
      1);
  EXPECT_EQ(read_file_text(dir / "err.txt"), "error: " + (dir / "small.png").string() + ": 16x24, but " +
                                                 (dir / "a.png").string() +
                                                 " is 32x24: the images must have the same size\n");
}

TEST(EvalCli, PerfectGaussians) {
  II_REQUIRE_CLI(exe);
  const fs::path dir = test::temp_dir("eval-cli");
  test::write_scene(dir / "scene");
  ASSERT_EQ(run(fmt::format("'{}' eval --scene '{}' --gaussians '{}' --normalized --height {} --device cpu --out '{}'", exe.string(),
                            (dir / "scene").string(), (dir / "scene" / "truth.ply").string(), test::kSceneHeight,
                            (dir / "out").string()),
                dir / "log.txt"),
            0)
      << read_file_text(dir / "log.txt");
  const json m = json::parse(read_file_text(dir / "out" / "metrics.json"));
  EXPECT_EQ(m["mean"]["psnr"], "inf");
  EXPECT_TRUE(fs::exists(dir / "out" / "report.html"));
  EXPECT_NE(read_file_text(dir / "log.txt").find("PSNR inf  SSIM 1.0000"), std::string::npos)
      << read_file_text(dir / "log.txt");
}

// The reference painted by LaMa (the small fixture of tests/inpaint in place of big-lama's
// weights) through the whole command a user runs; metrics.json names the file and its SHA-256.
TEST(EvalCli, ReferencePaintedByLama) {
  II_REQUIRE_CLI(exe);
  const fs::path dir = test::temp_dir("eval-cli-lama");
  test::write_scene(dir / "scene");
  const fs::path lama = fs::absolute("tests/inpaint/fixture/lama-small/models/best.ckpt");
  ASSERT_EQ(run(fmt::format("'{}' eval --scene '{}' --inpainter '{}' --height {} --device cpu --out '{}'", exe.string(),
                            (dir / "scene").string(), lama.string(), test::kSceneHeight, (dir / "out").string()),
                dir / "log.txt"),
            0)
      << read_file_text(dir / "log.txt");
  const json m = json::parse(read_file_text(dir / "out" / "metrics.json"));
  const json& inpainter = m["prediction"]["inpainter"];
  EXPECT_EQ(inpainter["name"], "lama") << m["prediction"];
  EXPECT_EQ(inpainter["network"], "LaMa FFC-ResNet (ngf 8, 2 blocks)");
  EXPECT_EQ(inpainter["sha256"].get<std::string>().size(), 64u);
  EXPECT_EQ(m["prediction"]["reference"], "lama");
  // A file that is not LaMa's: refused before any work, naming it.
  ASSERT_NE(run(fmt::format("'{}' eval --scene '{}' --inpainter '{}' --height {} --device cpu --out '{}'", exe.string(),
                            (dir / "scene").string(), (dir / "scene" / "truth.ply").string(), test::kSceneHeight,
                            (dir / "out2").string()),
                dir / "log2.txt"),
            0);
  EXPECT_NE(read_file_text(dir / "log2.txt").find((dir / "scene" / "truth.ply").string()), std::string::npos)
      << read_file_text(dir / "log2.txt");
}

}  // namespace
}  // namespace ii
