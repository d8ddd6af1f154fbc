// A click with a segmenter, end to end: `instainpaint masks --click --segmenter` on the statue
// with the small MobileSAM-layout fixture (tests/segment/fixture, seeded random weights): the
// clicked view's mask is the reference code's for that click (scripts/segmenter-reference wrote
// it), lifted to every other view with the default model's reconstruction and carved.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "data/scene.h"
#include "edit/scene_masks.h"
#include "io/image.h"
#include "test_support.h"

namespace ii {
namespace {
namespace clicked_mask_test {

const std::filesystem::path kFixture = "tests/segment/fixture";

TEST(ClickedMask, TheMasksCommandTakesTheSegmentersMaskAndLiftsItToEveryView) {
  const std::string missing = test::shared_missing("data/statue");
  if (!missing.empty()) GTEST_SKIP() << missing;
  const std::filesystem::path dir = test::temp_dir("clicked-mask");
  const std::string cli = test::cli_executable().string();
  ASSERT_EQ(test::run_command(cli + " masks --scene " + test::shared_path("data/statue").string() +
                                  " --view IMG_2707 --click 301.5,259.5 --segmenter " +
                                  (kFixture / "mobile_sam_small.pt").string() +
                                  " --precision fp32 --height 128 --device cpu --out " + (dir / "masks").string(),
                              dir / "log.txt"),
            0)
      << test::file_bytes(dir / "log.txt");
  EXPECT_NE(test::file_bytes(dir / "log.txt").find("clicked view's mask: MobileSAM TinyViT"), std::string::npos)
      << test::file_bytes(dir / "log.txt");

  // The clicked view: the reference code's mask (float products as it computes: at most a few
  // pixels where the logit is within 1e-4 of 0 may differ).
  const Image reference = read_mask(kFixture / "statue_IMG_2707_click.png");
  const Image clicked = read_mask(dir / "masks" / "IMG_2707.png");
  ASSERT_EQ(clicked.width, reference.width);
  ASSERT_EQ(clicked.height, reference.height);
  int64_t differ = 0, object = 0;
  for (size_t i = 0; i < clicked.pixels.size(); ++i) {
    differ += (clicked.pixels[i] > 0.5f) != (reference.pixels[i] > 0.5f);
    object += reference.pixels[i] > 0.5f;
  }
  EXPECT_GT(object, 1000);
  EXPECT_LE(differ, 5) << "of " << object << " object pixels";

  // Every other view has its lifted, carved mask; the report says how the clicked mask was made.
  const Scene scene = load_scene(test::shared_path("data/statue"));
  int covered = 0;
  for (const View& v : scene.views) {
    const Image m = read_mask(dir / "masks" / (v.name + ".png"));
    EXPECT_EQ(m.width, v.camera.K.width);
    covered += std::count(m.pixels.begin(), m.pixels.end(), 1.f) > 0;
  }
  EXPECT_GE(covered, static_cast<int>(scene.views.size()) - 2);
  const nlohmann::json report = nlohmann::json::parse(test::file_bytes(dir / "masks" / "masks.json"));
  EXPECT_EQ(report["clicked_mask"], "segmenter");
  EXPECT_EQ(report["segmenter"]["precision"], "fp32");
  EXPECT_NEAR(report["segmenter"]["pixels"].get<double>(), static_cast<double>(object), 5.0);
  EXPECT_GT(report["carved"].get<int>(), 0);
}

TEST(ClickedMask, NotClicksNeedASegmenter) {
  const std::string missing = test::shared_missing("data/statue");
  if (!missing.empty()) GTEST_SKIP() << missing;
  const std::filesystem::path dir = test::temp_dir("clicked-mask-not");
  const std::string cli = test::cli_executable().string();
  EXPECT_NE(test::run_command("env -u INSTAINPAINT_SEGMENTER " + cli + " masks --scene " +
                                  test::shared_path("data/statue").string() +
                                  " --view IMG_2707 --click 301,259 --not-click 20,20 --out " + (dir / "m").string(),
                              dir / "log.txt"),
            0);
  EXPECT_NE(test::file_bytes(dir / "log.txt").find("--not-click needs --segmenter (or INSTAINPAINT_SEGMENTER)"),
            std::string::npos)
      << test::file_bytes(dir / "log.txt");
}

}  // namespace clicked_mask_test
}  // namespace
}  // namespace ii
