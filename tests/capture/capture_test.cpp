// Capture: frame picking, the scene frame and pose comparison, and the clear errors of bad
// inputs (the COLMAP steps themselves: tests/data/colmap_scene_test.cpp with a fake colmap).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdlib>
#include <random>

#include "capture/capture.h"
#include "capture/frames.h"
#include "common/files.h"
#include "common/process.h"
#include "data/image_ops.h"
#include "data/scene.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

// A checkerboard of 4-pixel squares, and the same blurred (down and up again).
Image checkerboard(int w, int h) {
  Image im(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) im.at(y, x, c) = ((x / 4 + y / 4) % 2) ? 0.9f : 0.1f;
  return im;
}
Image blurred(const Image& im) { return resize_area(resize_area(im, im.width / 8, im.height / 8), im.width, im.height); }

bool have(const char* tool) { return !find_executable(tool).empty(); }

TEST(Frames, TheSharpFrameOfABlurredAndSharpPairIsPicked) {
  const Image sharp = checkerboard(64, 48), soft = blurred(sharp);
  EXPECT_GT(sharpness(sharp), 10 * sharpness(soft));
  const std::vector<double> scores = {sharpness(soft), sharpness(sharp), sharpness(sharp), sharpness(soft)};
  EXPECT_EQ(pick_sharpest(scores, 2), (std::vector<int>{1, 2}));
  EXPECT_EQ(pick_sharpest({1, 5, 2, 2, 9, 0}, 3), (std::vector<int>{1, 2, 4}));  // ties: the first
  EXPECT_EQ(pick_sharpest({3, 1}, 5), (std::vector<int>{0, 1}));                 // fewer than asked: all
  EXPECT_TRUE(pick_sharpest({}, 5).empty());
}

TEST(Frames, AVideosSharpestFrameOfEachStretch) {
  if (!have("ffmpeg")) GTEST_SKIP() << "no ffmpeg";
  const fs::path dir = test::temp_dir("capture-video");
  const Image sharp = checkerboard(96, 64), soft = blurred(sharp);
  for (int i = 0; i < 8; ++i) write_png(dir / "src" / fmt::format("{:02d}.png", i), (i == 1 || i == 2 || i == 5 || i == 6) ? sharp : soft);
  // Lossless (FFV1): the frames' sharpness survives the encoding exactly.
  ASSERT_EQ(std::system(fmt::format("ffmpeg -loglevel error -framerate 4 -i '{}' -c:v ffv1 '{}'",
                                    (dir / "src" / "%02d.png").string(), (dir / "clip.mkv").string())
                            .c_str()),
            0);
  const VideoFrames f = extract_video_frames(dir / "clip.mkv", dir / "frames", dir / "work", 4, 48);
  EXPECT_EQ(f.decoded, 8);
  EXPECT_EQ(f.picked, (std::vector<int>{1, 2, 5, 6}));
  ASSERT_EQ(list_images(dir / "frames").size(), 4u);
  const Image first = read_image_rgb(dir / "frames" / "frame_0001.png");
  EXPECT_EQ(first.width, 48);  // the long side limited to max_size
  EXPECT_EQ(first.height, 32);
  EXPECT_GT(sharpness(first), 0);
}

ColmapModel ring_of_cameras(uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, 0.05);
  ColmapModel m;
  const Eigen::Vector3d target(3, -2, 7), up = Eigen::Vector3d(0.3, 0.2, 1).normalized();
  const Eigen::Vector3d a = up.unitOrthogonal(), b = up.cross(a);
  for (int i = 0; i < 12; ++i) {
    const double t = 2 * M_PI * i / 12;
    const Eigen::Vector3d c = target + 5 * (std::cos(t) * a + std::sin(t) * b) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    const Eigen::Vector3d z = (target - c).normalized(), x = z.cross(up).normalized(), y = z.cross(x);  // y: down
    Eigen::Matrix3d c2w;
    c2w << x, y, z;
    ColmapImage im;
    im.id = i + 1;
    im.name = fmt::format("v{:02d}.png", i);
    const Eigen::Quaterniond q(c2w.transpose());
    im.qvec = Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
    im.tvec = -c2w.transpose() * c;
    m.images[im.id] = im;
  }
  for (int k = 0; k < 50; ++k) m.points[k].xyz = target + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  return m;
}

TEST(Capture, TheSceneFrameCentresScalesAndTurnsUpToMinusY) {
  const ColmapModel original = ring_of_cameras(3);
  ColmapModel m = original;
  apply_frame(m, sensible_frame(m));
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> centres;
  for (const auto& [id, im] : m.images) {
    const Eigen::Matrix3d r = Eigen::Quaterniond(im.qvec[0], im.qvec[1], im.qvec[2], im.qvec[3]).toRotationMatrix();
    up += -r.transpose() * Eigen::Vector3d::UnitY();
    centres.push_back(-r.transpose() * im.tvec);
  }
  EXPECT_LT((up.normalized() + Eigen::Vector3d::UnitY()).norm(), 1e-9);
  double spread = 0;
  for (const auto& a : centres)
    for (const auto& b : centres) spread = std::max(spread, (a - b).norm());
  EXPECT_NEAR(spread, 10.0, 1e-9);
  // Centred on the points (all near the ring's target).
  Eigen::Vector3d mean_point = Eigen::Vector3d::Zero();
  for (const auto& [id, p] : m.points) mean_point += p.xyz / m.points.size();
  EXPECT_LT(mean_point.norm(), 0.1);
  // The same views up to a similarity: no pose error.
  const PoseComparison c = compare_poses(poses_of(m), poses_of(original));
  EXPECT_EQ(c.matched, 12);
  EXPECT_LT(c.max_rotation_deg, 1e-6);
  EXPECT_LT(c.max_position, 1e-9);
  // A view turned by 2 degrees shows up as that.
  ColmapModel turned = m;
  const Eigen::Quaterniond q(turned.images[1].qvec[0], turned.images[1].qvec[1], turned.images[1].qvec[2],
                             turned.images[1].qvec[3]);
  const Eigen::Quaterniond t = Eigen::Quaterniond(Eigen::AngleAxisd(2 * M_PI / 180, Eigen::Vector3d::UnitX())) * q;
  turned.images[1].qvec = Eigen::Vector4d(t.w(), t.x(), t.y(), t.z());
  turned.images[1].tvec = Eigen::AngleAxisd(2 * M_PI / 180, Eigen::Vector3d::UnitX()) * turned.images[1].tvec;
  // After the best orientation alignment (which takes a twelfth of the turn), that view is
  // 11/12 of 2 degrees off and the others 1/12.
  const PoseComparison off = compare_poses(poses_of(turned), poses_of(original));
  EXPECT_NEAR(off.max_rotation_deg, 2.0 * 11 / 12, 1e-3);
  EXPECT_NEAR(off.median_rotation_deg, 2.0 / 12, 1e-3);
}

// COLMAP for real (Debian's colmap, CPU): 8 photos of a synthetic room (`synth`, exact poses)
// are all posed, and their poses agree with the room's within a degree and 2 % of the spread.
TEST(Capture, ASyntheticRoomsPhotosArePosedLikeItsCameras) {
  II_REQUIRE_CLI(exe);
  if (!have("colmap")) GTEST_SKIP() << "no colmap (scripts/install-deps.sh installs it)";
  const fs::path dir = test::temp_dir("capture-room");
  const fs::path log = dir / "synth.log";
  ASSERT_EQ(test::run_command(exe.string() + " synth --out '" + (dir / "rooms").string() +
                                  "' --scenes 1 --seed 21 --views 8 --test-views 0 --width 320 --height 240 --degrade none",
                              log),
            0)
      << read_file_text(log);
  const fs::path room = dir / "rooms" / "scene_000";
  const nlohmann::json report = capture_scene(room / "images_4", dir / "scene");
  EXPECT_EQ(report["images"], 8);
  EXPECT_EQ(report["registered"], 8);
  // Photos in name order: sequential matching poses them all, no exhaustive pass.
  EXPECT_EQ(report["matcher"], "sequential");
  const Scene captured = load_scene(dir / "scene");
  EXPECT_EQ(captured.format, "colmap");
  ASSERT_EQ(captured.views.size(), 8u);
  const PoseComparison c = compare_poses(poses_of_scene(dir / "scene"), poses_of_scene(room));
  EXPECT_EQ(c.matched, 8);
  EXPECT_LT(c.median_rotation_deg, 1.0);
  EXPECT_LT(c.median_position, 0.02);
}

TEST(Capture, BadInputsAreClearErrors) {
  const fs::path dir = test::temp_dir("capture-bad");
  CaptureOptions o;
  o.colmap = "sh";  // found; never reached in these cases
  EXPECT_EQ(test::error_message([&] { capture_scene(dir / "absent.mp4", dir / "out", o); }),
            (dir / "absent.mp4").string() + ": not found (give a video file or a folder of photos)");
  write_png(dir / "two" / "a.png", checkerboard(32, 32));
  write_png(dir / "two" / "b.jpg.png", checkerboard(32, 32));
  EXPECT_EQ(test::error_message([&] { capture_scene(dir / "two", dir / "out-two", o); }),
            (dir / "two").string() + ": holds 2 image(s) (png, jpg); posing needs at least 3, better 20 or more with "
                                     "much overlap");
  write_png(dir / "three" / "a.png", checkerboard(32, 32));
  write_png(dir / "three" / "b.png", checkerboard(32, 32));
  write_file_atomic(dir / "three" / "c.jpg", std::string("not a JPEG"));
  const std::string unreadable = test::error_message([&] { capture_scene(dir / "three", dir / "out-three", o); });
  EXPECT_EQ(unreadable.rfind((dir / "three" / "c.jpg").string() + ": ", 0), 0u) << unreadable;
  write_file_atomic(dir / "notes.mp4", std::string("not a video"));
  if (have("ffmpeg")) {
    const std::string msg = test::error_message([&] { capture_scene(dir / "notes.mp4", dir / "out-notes", o); });
    EXPECT_EQ(msg.rfind((dir / "notes.mp4").string() + ": no video stream that ffmpeg can read (", 0), 0u) << msg;
  }
  write_file_atomic(dir / "full" / "x.txt", std::string("x"));
  EXPECT_EQ(test::error_message([&] { capture_scene(dir / "two", dir / "full", o); }),
            (dir / "full").string() + ": already exists; give a new folder (nothing there is overwritten)");
  o.colmap = "/nonexistent/colmap";
  EXPECT_EQ(test::error_message([&] { capture_scene(dir / "two", dir / "out-x", o); }),
            "COLMAP is not installed ('/nonexistent/colmap' not found): `apt install colmap` "
            "(scripts/install-deps.sh does it) or give its path with --colmap");
  o.colmap = "sh";
  o.matcher = "vocab_tree";
  EXPECT_EQ(test::error_message([&] { capture_scene(dir / "two", dir / "out-y", o); }),
            "unknown matcher 'vocab_tree' (auto, sequential or exhaustive)");
}

}  // namespace
}  // namespace ii
