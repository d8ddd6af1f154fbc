// Training mask generators: size ranges, shapes, mixing, and ellipses carried across views
// through depth.
#include <gtest/gtest.h>

#include <cmath>

#include <Eigen/Geometry>

#include "data/masks.h"
#include "io/npy.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

double mask_sum(const Image& m) {
  double s = 0;
  for (float v : m.pixels) s += v;
  return s;
}

// mt19937_64 output is fixed by the C++ standard and the draws are ours: golden values hold anywhere.
TEST(Masks, DrawsAreUniformAndTheSameOnEveryToolchain) {
  MaskRng rng(1);
  std::vector<int> first;
  for (int k = 0; k < 6; ++k) first.push_back(random_int(rng, 0, 99));
  EXPECT_EQ(first, (std::vector<int>{13, 13, 45, 2, 35, 91}));
  std::vector<int> order = {0, 1, 2, 3, 4, 5};
  random_shuffle(order, rng);
  EXPECT_EQ(order, (std::vector<int>{3, 4, 1, 5, 0, 2}));
  int counts[3] = {0, 0, 0};
  double lowest = 1, highest = 0;
  for (int k = 0; k < 30000; ++k) {
    ++counts[random_int(rng, -1, 1) + 1];
    const double u = random_unit(rng);
    lowest = std::min(lowest, u), highest = std::max(highest, u);
  }
  for (int c : counts) EXPECT_NEAR(c / 30000.0, 1 / 3.0, 0.01);
  EXPECT_GE(lowest, 0.0);
  EXPECT_LT(lowest, 1e-3);
  EXPECT_LT(highest, 1.0);
  EXPECT_EQ(random_int(rng, 7, 7), 7);
  EXPECT_EQ(test::error_message([&] { random_int(rng, 2, 1); }), "random_int: empty range [2, 1]");
}

TEST(Masks, RectangleSizesAndPositionsFollowTheOfficialRanges) {
  MaskRng rng(11);
  const int W = 512, H = 384;
  int min_w = W, max_w = 0, min_h = H, max_h = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const auto rects = random_rectangles(W, H, 1 + trial % 4, rng);
    ASSERT_EQ(rects.size(), static_cast<size_t>(1 + trial % 4));
    for (const Rectangle& r : rects) {
      min_w = std::min(min_w, r.width), max_w = std::max(max_w, r.width);
      min_h = std::min(min_h, r.height), max_h = std::max(max_h, r.height);
      EXPECT_GE(r.x, 0);
      EXPECT_GE(r.y, 0);
      EXPECT_LT(r.x + r.width, W);  // top-left x in [0, W - width)
      EXPECT_LT(r.y + r.height, H);
    }
  }
  // [W/6, W/4) = [85, 128) and [H/6, H/4) = [64, 96), both ends reached.
  EXPECT_EQ(min_w, 85);
  EXPECT_EQ(max_w, 127);
  EXPECT_EQ(min_h, 64);
  EXPECT_EQ(max_h, 95);

  const Image m = rectangles_mask(40, 30, {{2, 3, 5, 4}, {4, 5, 5, 4}});
  EXPECT_EQ(mask_sum(m), 20 + 20 - 3 * 2);  // union: the 3x2 overlap counts once
  EXPECT_EQ(m.at(3, 2), 1.f);
  EXPECT_EQ(m.at(2, 2), 0.f);
  EXPECT_EQ(m.at(8, 8), 1.f);
  EXPECT_EQ(m.at(9, 8), 0.f);
}

TEST(Masks, EllipseAxesAndShape) {
  MaskRng rng(5);
  for (int count : {1, 2, 3, 4}) {
    const int a0 = count <= 2 ? 512 / 8 : 512 / 12, a1 = count <= 2 ? 512 / 6 : 512 / 8;
    for (int trial = 0; trial < 200; ++trial)
      for (const Ellipse& e : random_ellipses(512, 512, count, rng)) {
        EXPECT_GE(e.major, a0 + 1);
        EXPECT_LT(e.major, a1);
        EXPECT_GE(e.minor, a0);
        EXPECT_LT(e.minor, e.major);
        EXPECT_GE(e.angle, 0);
        EXPECT_LT(e.angle, M_PI);
        EXPECT_GE(e.center_x, 0);
        EXPECT_LT(e.center_x, 512);
      }
  }
  // Major axis along (cos a, -sin a) in (column, row), minor along (sin a, cos a).
  Ellipse e;
  e.center_x = 50, e.center_y = 40, e.major = 20, e.minor = 8, e.angle = 0.4;
  const Image m = ellipses_mask(100, 80, {e});
  auto at = [&](double along_major, double along_minor) {
    const double x = e.center_x + along_major * std::cos(e.angle) + along_minor * std::sin(e.angle);
    const double y = e.center_y - along_major * std::sin(e.angle) + along_minor * std::cos(e.angle);
    return m.at(static_cast<int>(std::lround(y)), static_cast<int>(std::lround(x)));
  };
  EXPECT_EQ(at(0, 0), 1.f);
  EXPECT_EQ(at(18, 0), 1.f);
  EXPECT_EQ(at(-18, 0), 1.f);
  EXPECT_EQ(at(0, 6.5), 1.f);
  EXPECT_EQ(at(23, 0), 0.f);
  EXPECT_EQ(at(0, 10.5), 0.f);
  EXPECT_NEAR(mask_sum(m), M_PI * 20 * 8, 0.04 * M_PI * 20 * 8);
}

TEST(Masks, DilationGrowsBySquareKernels) {
  Image m(21, 21, 1);
  m.at(10, 10) = 1.f;
  EXPECT_EQ(mask_sum(dilate_mask(m, 1, 5)), 25);
  const Image twice = dilate_mask(m, 2, 5);
  EXPECT_EQ(mask_sum(twice), 81);
  EXPECT_EQ(twice.at(6, 6), 1.f);
  EXPECT_EQ(twice.at(5, 10), 0.f);
  EXPECT_EQ(test::error_message([&] { dilate_mask(Image(4, 4, 3)); }),
            "dilate_mask: expected a 1-channel mask, got 3 channels");
}

TEST(Masks, ModeMixFollowsTheRatios) {
  MaskRng rng(3);
  int counts[3] = {0, 0, 0};
  const int n = 40000;
  for (int k = 0; k < n; ++k) ++counts[static_cast<int>(draw_mask_mode({1, 2, 1}, rng))];
  EXPECT_NEAR(counts[0] / double(n), 0.25, 0.01);
  EXPECT_NEAR(counts[1] / double(n), 0.50, 0.01);
  EXPECT_NEAR(counts[2] / double(n), 0.25, 0.01);
  for (int k = 0; k < 100; ++k) EXPECT_EQ(draw_mask_mode({0, 0, 3}, rng), MaskMode::Consistent3D);
  EXPECT_EQ(mask_mode_name(MaskMode::Consistent3D), "3dconsistent");
  EXPECT_EQ(test::error_message([&] { draw_mask_mode({0, 0, 0}, rng); }), "mask mix weights (0, 0, 0) sum to zero");
  EXPECT_EQ(test::error_message([&] { draw_mask_mode({1, -1, 0}, rng); }),
            "mask mix weights must be finite and non-negative, got (1, -1, 0)");
}

Camera make_camera(int w, int h, double f, const Eigen::Vector3d& center, const Eigen::Matrix3d& rotation) {
  Camera c;
  c.K = {w, h, f, f, w / 2.0, h / 2.0};
  c.c2w.block<3, 3>(0, 0) = rotation;
  c.c2w.block<3, 1>(0, 3) = center;
  return c;
}

// Pixel of camera `cam` where world point X lands, or false when outside / behind.
bool project(const Camera& cam, const Eigen::Vector3d& X, int& row, int& col) {
  const Eigen::Matrix4d w2c = cam.w2c_opencv();
  const Eigen::Vector3d Y = w2c.block<3, 3>(0, 0) * X + w2c.block<3, 1>(0, 3);
  if (Y.z() <= 0) return false;
  const double u = cam.K.fx * Y.x() / Y.z() + cam.K.cx, v = cam.K.fy * Y.y() / Y.z() + cam.K.cy;
  if (u < 0 || v < 0 || u >= cam.K.width || v >= cam.K.height) return false;
  row = static_cast<int>(v), col = static_cast<int>(u);
  return true;
}

// World point of camera pixel (row, col) at z-depth `depth`.
Eigen::Vector3d unproject(const Camera& cam, int row, int col, double depth) {
  const Eigen::Vector3d d((col + 0.5 - cam.K.cx) / cam.K.fx, -(row + 0.5 - cam.K.cy) / cam.K.fy, -1.0);
  return cam.center() + depth * (cam.rotation() * d);
}

TEST(Masks, EllipsesCarriedThroughAPlaneLandInsideTheOtherMasks) {
  // Reference looks down -z from the origin at a wall 4 units away; the other cameras moved
  // sideways / closer and turned a little, one with other intrinsics and size.
  const Camera ref = make_camera(64, 48, 60, {0, 0, 0}, Eigen::Matrix3d::Identity());
  const std::vector<Camera> others = {
      make_camera(64, 48, 60, {0.6, 0.2, 0}, Eigen::AngleAxisd(0.12, Eigen::Vector3d::UnitY()).toRotationMatrix()),
      make_camera(80, 40, 45, {-0.5, 0.1, -1.0},
                  Eigen::AngleAxisd(-0.1, Eigen::Vector3d::UnitX()).toRotationMatrix()),
      ref};
  const double wall = 4.0;
  const Image depth(64, 48, 1, static_cast<float>(wall));
  MaskRng rng(9);
  const Image ellipses = ellipses_mask(64, 48, random_ellipses(64, 48, 2, rng));
  ASSERT_GT(mask_sum(ellipses), 50);
  const std::vector<Image> carried = carry_mask_through_depth(ellipses, depth, ref, others, 2);
  ASSERT_EQ(carried.size(), 3u);
  EXPECT_EQ(carried[1].width, 80);

  const Image ellipses_margin = dilate_mask(ellipses, 3, 5);
  for (size_t c = 0; c < others.size(); ++c) {
    int landed = 0;
    // Every reference pixel inside the ellipses lands inside the other view's mask.
    for (int i = 0; i < 48; ++i)
      for (int j = 0; j < 64; ++j) {
        if (ellipses.at(i, j) < 0.5f) continue;
        int row = 0, col = 0;
        if (!project(others[c], unproject(ref, i, j, wall), row, col)) continue;
        ++landed;
        EXPECT_EQ(carried[c].at(row, col), 1.f) << "camera " << c << " pixel " << i << "," << j;
      }
    EXPECT_GT(landed, 20) << "camera " << c;
    // And the mask holds nothing far from the ellipses: its pixels, put on the wall and seen
    // from the reference, fall near the ellipses (two 5x5 dilations, scaled by the zoom).
    for (int i = 0; i < carried[c].height; ++i)
      for (int j = 0; j < carried[c].width; ++j) {
        if (carried[c].at(i, j) < 0.5f) continue;
        const Camera& cam = others[c];
        // Depth of the wall (world z = -4) along this pixel's ray.
        const Eigen::Vector3d dir = cam.rotation() *
            Eigen::Vector3d((j + 0.5 - cam.K.cx) / cam.K.fx, -(i + 0.5 - cam.K.cy) / cam.K.fy, -1.0);
        const double t = (-wall - cam.center().z()) / dir.z();
        int row = 0, col = 0;
        if (!project(ref, cam.center() + t * dir, row, col)) continue;
        EXPECT_EQ(ellipses_margin.at(row, col), 1.f) << "camera " << c << " pixel " << i << "," << j;
      }
  }
  // The reference itself: the ellipses dilated twice, exactly.
  EXPECT_EQ(carried[2].pixels, dilate_mask(ellipses, 2, 5).pixels);
}

TEST(Masks, PointsBehindACameraAndUnknownDepthAreDropped) {
  const Camera ref = make_camera(32, 32, 30, {0, 0, 0}, Eigen::Matrix3d::Identity());
  const Camera backwards =
      make_camera(32, 32, 30, {0, 0, -1}, Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix());
  const Image full(32, 32, 1, 1.f);
  EXPECT_EQ(mask_sum(carry_mask_through_depth(full, Image(32, 32, 1, 3.f), ref, {backwards})[0]), 0);
  Image unknown(32, 32, 1, 0.f);
  unknown.at(16, 16) = NAN;
  EXPECT_EQ(mask_sum(carry_mask_through_depth(full, unknown, ref, {ref})[0]), 0);
  EXPECT_EQ(test::error_message([&] { carry_mask_through_depth(full, Image(16, 16, 1, 3.f), ref, {ref}); }),
            "carry_mask_through_depth: reference depth is 16x16x1, its camera is 32x32");
}

TEST(Masks, DepthFolderIsReadAndChecked) {
  Scene scene;
  scene.root = test::temp_dir("depth-scene");
  View view;
  view.name = "frame_003";
  view.image_path = scene.root / "images" / "frame_003.png";
  view.camera.K = {4, 3, 5, 5, 2, 1.5};
  EXPECT_FALSE(load_view_depth(scene, view).has_value());
  fs::create_directories(scene.root / "depth");
  std::vector<double> values(12);
  for (int k = 0; k < 12; ++k) values[k] = 1.5 + k;
  write_npy(scene.root / "depth" / "frame_003.npy", values, {3, 4});
  const auto depth = load_view_depth(scene, view);
  ASSERT_TRUE(depth.has_value());
  EXPECT_EQ(depth->width, 4);
  EXPECT_EQ(depth->at(2, 1), 10.5f);
  view.camera.K.width = 5;
  EXPECT_EQ(test::error_message([&] { load_view_depth(scene, view); }),
            (scene.root / "depth" / "frame_003.npy").string() + ": depth is 4x3 but the view is 5x3");
}

TEST(Masks, SixteenBitDepthPngsAreScaledLevels) {
  const fs::path dir = test::temp_dir("depth-png");
  Image levels(3, 2, 1);
  levels.at(0, 0) = 1000.f / 65535.f;
  levels.at(1, 2) = 65535.f / 65535.f;
  write_png(dir / "d.png", levels, 16);
  const Image depth = read_depth_map(dir / "d.png", 3, 2, 0.001);
  EXPECT_FLOAT_EQ(depth.at(0, 0), 1.0f);
  EXPECT_FLOAT_EQ(depth.at(1, 2), 65.535f);
  EXPECT_EQ(depth.at(0, 1), 0.f);  // level 0: unknown
  write_png(dir / "e.png", levels, 8);
  EXPECT_EQ(test::error_message([&] { read_depth_map(dir / "e.png", 3, 2); }),
            (dir / "e.png").string() + ": a depth image must be a 16-bit PNG (or a .npy array)");
  EXPECT_EQ(test::error_message([&] { read_depth_map(dir / "d.png", 4, 2); }),
            (dir / "d.png").string() + ": depth is 3x2 but the view is 4x2");
}

TEST(Masks, TypicalDepthFallbacks) {
  Scene scene;
  scene.root = test::temp_dir("typical-depth");
  scene.format = "nerfstudio";
  // Cameras on a circle of radius 3 looking at the origin: the axes meet there.
  std::vector<Camera> ring;
  for (int k = 0; k < 6; ++k) {
    const double a = 0.3 * k;
    const Eigen::Vector3d c(3 * std::sin(a), 0.5, 3 * std::cos(a));
    const Eigen::Vector3d back = c.normalized();
    const Eigen::Vector3d right = Eigen::Vector3d::UnitY().cross(back).normalized();
    Eigen::Matrix3d R;
    R << right, back.cross(right), back;
    ring.push_back(make_camera(32, 32, 30, c, R));
  }
  const double expected = ring[0].center().norm();  // the origin seen from camera 0
  EXPECT_NEAR(typical_scene_depth(scene, ring[0], ring), expected, 1e-6);
  // Forward-facing (parallel axes): twice the spread of the centres.
  std::vector<Camera> line;
  for (int k = 0; k < 3; ++k) line.push_back(make_camera(32, 32, 30, {k - 1.0, 0, 0}, Eigen::Matrix3d::Identity()));
  EXPECT_NEAR(typical_scene_depth(scene, line[0], line), 2.0, 1e-9);
  // Depth bounds win over camera geometry.
  scene.near = 2.0, scene.far = 8.0;
  EXPECT_NEAR(typical_scene_depth(scene, ring[0], ring), 4.0, 1e-12);
}

TEST(Masks, TypicalDepthFromFernPoints) {
  II_REQUIRE_SHARED(dir, "data/fern");
  const Scene scene = load_scene(dir);
  ASSERT_TRUE(scene.near && scene.far);
  std::vector<Camera> cameras;
  for (const View& v : scene.views) cameras.push_back(v.camera);
  const double d = typical_scene_depth(scene, cameras[5], cameras);
  // The median of the COLMAP points, inside LLFF's bounds and not their geometric mean.
  EXPECT_GT(d, *scene.near);
  EXPECT_LT(d, *scene.far);
  EXPECT_GT(std::abs(d - std::sqrt(*scene.near * *scene.far)), 1e-3);
}

}  // namespace
}  // namespace ii
