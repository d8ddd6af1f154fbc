// `instainpaint render` end to end: runs the built executable (beside the tests' folder);
// skipped when it has not been built.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>

#include <nlohmann/json.hpp>

#include "common/files.h"
#include "io/image.h"
#include "io/ply.h"
#include "camera/trajectory.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

// A small cloud of splats around the origin (pre-activation values, as PLYs store them).
SplatCloud small_cloud() {
  SplatCloud c;
  for (int i = 0; i < 200; ++i) {
    const float t = i * 0.1f;
    const float p[3] = {std::sin(t) * 0.5f, std::cos(1.3f * t) * 0.5f, std::sin(0.7f * t) * 0.5f};
    for (int k = 0; k < 3; ++k) {
      c.means.push_back(p[k]);
      c.normals.push_back(0);
      c.sh_dc.push_back(k == 0 ? 1.5f : -1.0f);  // reddish
      c.log_scales.push_back(std::log(0.05f));
    }
    c.opacity_logit.push_back(2.f);
    c.rotations.insert(c.rotations.end(), {1, 0, 0, 0});
  }
  return c;
}

TEST(RenderCli, CameraListWithDepthAndAlpha) {
  II_REQUIRE_CLI(exe);
  const fs::path dir = test::temp_dir("render-cli");
  write_splat_ply(dir / "cloud.ply", small_cloud());
  NamedCamera cam;
  cam.name = "front";
  cam.camera.K = Intrinsics::from_fov(48, 32, 1.2, 0.9);
  cam.camera.c2w = look_at({0, 0, 3}, {0, 0, 0}, Eigen::Vector3d::UnitY());
  NamedCamera side = cam;
  side.name = "side";
  side.camera.c2w = look_at({3, 0, 0}, {0, 0, 0}, Eigen::Vector3d::UnitY());
  write_camera_json(dir / "cams.json", {cam, side});

  const fs::path out = dir / "out";
  ASSERT_EQ(test::run_command(
                fmt::format("'{}' render --ply '{}' --cameras '{}' --out '{}' --depth --alpha --no-video --threads 1 "
                            "--device cpu",
                            exe.string(), (dir / "cloud.ply").string(), (dir / "cams.json").string(), out.string()),
                dir / "log.txt"),
            0)
      << read_file_text(dir / "log.txt");
  for (const char* kind : {"rgb", "depth", "alpha"})
    for (const char* f : {"0000.png", "0001.png"}) ASSERT_TRUE(fs::exists(out / kind / f)) << kind << "/" << f;
  const Image rgb = read_image_rgb(out / "rgb" / "0000.png");
  EXPECT_EQ(rgb.width, 48);
  EXPECT_EQ(rgb.height, 32);
  // Red splats in the middle, white background in a corner.
  EXPECT_GT(rgb.at(16, 24, 0), rgb.at(16, 24, 1) + 0.2f);
  EXPECT_GT(rgb.at(0, 0, 1), 0.95f);
  const auto cams = read_camera_json(out / "cameras.json");
  ASSERT_EQ(cams.size(), 2u);
  EXPECT_EQ(cams[1].name, "side");
  const nlohmann::json summary = nlohmann::json::parse(read_file_text(out / "render.json"));
  EXPECT_EQ(summary["device"], "cpu");
  EXPECT_EQ(summary["frames"], 2);
  EXPECT_FALSE(fs::exists(out / "rgb.mp4"));
}

TEST(RenderCli, TurntableVideo) {
  II_REQUIRE_CLI(exe);
  if (std::system("command -v ffmpeg > /dev/null 2>&1") != 0) GTEST_SKIP() << "no ffmpeg";
  const fs::path dir = test::temp_dir("render-cli-video");
  write_splat_ply(dir / "cloud.ply", small_cloud());
  const fs::path out = dir / "out";
  ASSERT_EQ(
      test::run_command(
          fmt::format("'{}' render --ply '{}' --trajectory turntable --frames 4 --width 33 --height 21 --out '{}'",
                      exe.string(), (dir / "cloud.ply").string(), out.string()),
          dir / "log.txt"),
      0)
      << read_file_text(dir / "log.txt");
  EXPECT_TRUE(fs::exists(out / "rgb" / "0003.png"));
  ASSERT_TRUE(fs::exists(out / "rgb.mp4"));
  EXPECT_GT(fs::file_size(out / "rgb.mp4"), 100u);
  EXPECT_NE(read_file_text(dir / "log.txt").find("4/4 frames"), std::string::npos);  // progress bar
}

TEST(RenderCli, MissingCamerasIsAnError) {
  II_REQUIRE_CLI(exe);
  const fs::path dir = test::temp_dir("render-cli-err");
  write_splat_ply(dir / "cloud.ply", small_cloud());
  EXPECT_NE(test::run_command(fmt::format("'{}' render --ply '{}' --out '{}'", exe.string(),
                                          (dir / "cloud.ply").string(), (dir / "o").string()),
                              dir / "log.txt"),
            0);
  EXPECT_NE(read_file_text(dir / "log.txt").find("no cameras"), std::string::npos);
  EXPECT_NE(test::run_command(fmt::format("'{}' render --ply '{}' --trajectory orbit --out '{}'", exe.string(),
                                          (dir / "cloud.ply").string(), (dir / "o").string()),
                              dir / "log.txt"),
            0);
  EXPECT_NE(read_file_text(dir / "log.txt").find("needs --scene"), std::string::npos);
}

}  // namespace
}  // namespace ii
