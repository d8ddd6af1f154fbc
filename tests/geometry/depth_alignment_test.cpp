// The network's depth scaled to a scene's own points: a view whose predicted depth is twice the
// truth comes back onto the points (depth, positions and sizes alike); too few points, or
// points that fall in the view's mask, change nothing; with detail a box the network drew at the
// floor's depth comes onto its points where one scale cannot, hidden points do not pull it, and
// far from every point the scale alone holds; and a scene's points come from its depth maps, else
// from its photos.
#include <gtest/gtest.h>

#include <cmath>

#include "camera/trajectory.h"
#include "data/masks.h"
#include "geometry/depth_alignment.h"
#include "predict/predictor.h"
#include "synthetic_room.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace depth_alignment_test {

constexpr int kW = 32, kH = 24;

Camera test_camera() {
  Camera c;
  c.K = Intrinsics::from_fov(kW, kH, 60 * M_PI / 180, 2 * std::atan(std::tan(30 * M_PI / 180) * kH / kW));
  c.c2w = look_at({0.3, 0.2, 3}, {0, 0, 0}, {0, 1, 0});
  return c;
}

// One view in front of the plane z = 0 (its true depth at each pixel), the network's depth
// `factor` times that, positions on those rays, sizes 0.01.
struct OneView {
  SceneInput input;
  GaussianMaps maps;
  torch::Tensor truth;  // (H, W) true depth
};

OneView one_view(double factor) {
  OneView o;
  PreparedView view;
  view.name = "v";
  view.rgb = Image(kW, kH, 3, 0.5f);
  view.mask = Image(kW, kH, 1);
  view.camera = test_camera();
  o.input.views = {view};
  const Rays rays = compute_rays(view.camera);
  o.truth = torch::zeros({kH, kW});
  torch::Tensor xyz = torch::zeros({1, 1, 3, kH, kW});
  for (int i = 0; i < kH * kW; ++i) {
    const double oz = rays.origin[3 * i + 2], dz = rays.dir_unnorm[3 * i + 2];
    const double t = -oz / dz;  // the plane z = 0
    o.truth.view({-1})[i] = static_cast<float>(t);
    for (int c = 0; c < 3; ++c)
      xyz[0][0][c].view({-1})[i] = static_cast<float>(rays.origin[3 * i + c] + factor * t * rays.dir_unnorm[3 * i + c]);
  }
  o.maps.depth = (o.truth * factor).view({1, 1, 1, kH, kW});
  o.maps.xyz = xyz;
  o.maps.scale = torch::full({1, 1, 3, kH, kW}, 0.01);
  return o;
}

std::vector<Eigen::Vector3d> plane_points(int n) {
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) points.emplace_back(-0.8 + 1.6 * (i % 10) / 9.0, -0.5 + 1.0 * (i / 10) / 9.0, 0.0);
  return points;
}

TEST(DepthAlignment, ADepthTwiceTooFarComesBackOntoThePoints) {
  OneView o = one_view(2.0);
  const std::vector<DepthAlignment> a = align_depth_to_points(o.maps, o.input, plane_points(100));
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].view, "v");
  EXPECT_NEAR(a[0].scale, 0.5, 1e-3);
  EXPECT_GE(a[0].points, 50);
  EXPECT_LT((o.maps.depth.view({kH, kW}) - o.truth).abs().max().item<double>(), 1e-3 * o.truth.max().item<double>());
  EXPECT_LT(o.maps.xyz[0][0][2].abs().max().item<double>(), 1e-3) << "the positions are on the plane z = 0";
  EXPECT_NEAR(o.maps.scale.max().item<double>(), 0.005, 1e-5);
}

TEST(DepthAlignment, TooFewPointsOrPointsInTheMaskChangeNothing) {
  OneView few = one_view(2.0);
  const torch::Tensor before = few.maps.depth.clone();
  EXPECT_EQ(align_depth_to_points(few.maps, few.input, plane_points(10))[0].scale, 1.0);
  EXPECT_TRUE(torch::equal(few.maps.depth, before));
  // The whole view masked: every point falls in the mask.
  OneView masked = one_view(2.0);
  masked.input.views[0].mask = Image(kW, kH, 1, 1.f);
  const std::vector<DepthAlignment> a = align_depth_to_points(masked.maps, masked.input, plane_points(100));
  EXPECT_EQ(a[0].scale, 1.0);
  EXPECT_EQ(a[0].points, 0);
}

// A view of the plane z = 0 with a box standing on it (the middle third of the picture, at
// `box` times the plane's depth there): its true depth, and points on that surface at every
// `stride`-th pixel (`hidden`: also a point of the plane behind the box beside each box point,
// as another view would see it).
struct BoxView {
  OneView view;
  torch::Tensor truth;  // (H, W)
  torch::Tensor in_box;  // (H, W) bool
  std::vector<Eigen::Vector3d> points;
};

BoxView box_view(double predicted_factor, double box, int stride, bool hidden) {
  BoxView b;
  b.view = one_view(predicted_factor);  // the network: the plane alone, predicted_factor too far
  const Camera camera = b.view.input.views[0].camera;
  const Rays rays = compute_rays(camera);
  b.truth = b.view.truth.clone();
  b.in_box = torch::zeros({kH, kW}, torch::kBool);
  for (int y = kH / 3; y < 2 * kH / 3; ++y)
    for (int x = kW / 3; x < 2 * kW / 3; ++x) {
      b.truth[y][x] = b.truth[y][x].item<float>() * static_cast<float>(box);
      b.in_box[y][x] = true;
    }
  auto point_at = [&](int y, int x, double depth) {
    const size_t i = 3 * (static_cast<size_t>(y) * kW + x);
    return Eigen::Vector3d(rays.origin[i] + depth * rays.dir_unnorm[i],
                           rays.origin[i + 1] + depth * rays.dir_unnorm[i + 1],
                           rays.origin[i + 2] + depth * rays.dir_unnorm[i + 2]);
  };
  for (int y = stride / 2; y < kH; y += stride)
    for (int x = stride / 2; x < kW; x += stride) {
      b.points.push_back(point_at(y, x, b.truth[y][x].item<double>()));
      if (hidden && b.in_box[y][x].item<bool>())  // the plane behind the box, one pixel aside
        b.points.push_back(point_at(y, x + 1, b.view.truth[y][x + 1].item<double>()));
    }
  return b;
}

double box_error(const BoxView& b) {  // mean |log(depth / truth)| on the box
  const torch::Tensor d = b.view.maps.depth.view({kH, kW});
  return (d / b.truth).log().abs().masked_select(b.in_box).mean().item<double>();
}

TEST(DepthAlignment, WithDetailABoxDrawnAtTheFloorsDepthComesOntoItsPoints) {
  BoxView scale_only = box_view(2.0, 0.5, 2, false);
  DepthDetailOptions none;
  none.detail = 0;
  align_depth_to_points(scale_only.view.maps, scale_only.view.input, scale_only.points, none);
  EXPECT_GT(box_error(scale_only), 0.4) << "one scale leaves the box at the plane's depth";

  BoxView detailed = box_view(2.0, 0.5, 2, false);
  DepthDetailOptions detail;
  detail.detail = 1;
  const std::vector<DepthAlignment> a =
      align_depth_to_points(detailed.view.maps, detailed.view.input, detailed.points, detail);
  EXPECT_LT(box_error(detailed), 0.15);
  EXPECT_GT(a[0].detail_mean, 0.05);
  // Positions and sizes follow the depth: each Gaussian stays on its ray at the new depth.
  const Camera camera = detailed.view.input.views[0].camera;
  const int y = kH / 2, x = kW / 2;
  const torch::Tensor xyz = detailed.view.maps.xyz[0][0];
  const Eigen::Vector3d p(xyz[0][y][x].item<double>(), xyz[1][y][x].item<double>(), xyz[2][y][x].item<double>());
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  const double z = (w2c.block<3, 3>(0, 0) * p + w2c.block<3, 1>(0, 3)).z();
  EXPECT_NEAR(z, detailed.view.maps.depth[0][0][0][y][x].item<double>(), 1e-4);
  const double factor =
      detailed.view.maps.depth[0][0][0][y][x].item<double>() / (2.0 * detailed.view.truth[y][x].item<double>());
  EXPECT_NEAR(detailed.view.maps.scale[0][0][0][y][x].item<double>(), 0.01 * factor, 1e-6);
}

TEST(DepthAlignment, HiddenPointsBehindTheBoxDoNotPullIt) {
  DepthDetailOptions detail;
  detail.detail = 1;
  BoxView clean = box_view(2.0, 0.5, 2, false), hidden = box_view(2.0, 0.5, 2, true);
  align_depth_to_points(clean.view.maps, clean.view.input, clean.points, detail);
  align_depth_to_points(hidden.view.maps, hidden.view.input, hidden.points, detail);
  EXPECT_LT(box_error(hidden), box_error(clean) + 0.02);
  detail.front = 1e9;  // every point counts: the plane's behind the box drag it back
  BoxView unfiltered = box_view(2.0, 0.5, 2, true);
  align_depth_to_points(unfiltered.view.maps, unfiltered.view.input, unfiltered.points, detail);
  EXPECT_GT(box_error(unfiltered), box_error(clean) + 0.1);
}

TEST(DepthAlignment, FarFromEveryPointTheScaleAloneHolds) {
  // Points on the left quarter only, the box among them; the right edge is many spacings away.
  BoxView b = box_view(2.0, 0.5, 1, false);
  std::vector<Eigen::Vector3d> left;
  const Camera camera = b.view.input.views[0].camera;
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  for (const Eigen::Vector3d& p : b.points) {
    const Eigen::Vector3d c = w2c.block<3, 3>(0, 0) * p + w2c.block<3, 1>(0, 3);
    if (camera.K.fx * c.x() / c.z() + camera.K.cx < kW / 4.0) left.push_back(p);
  }
  ASSERT_GE(left.size(), 50u);
  DepthDetailOptions detail;
  detail.detail = 0.5;
  const std::vector<DepthAlignment> a = align_depth_to_points(b.view.maps, b.view.input, left, detail);
  EXPECT_NEAR(a[0].scale, 0.5, 1e-3);
  const torch::Tensor right =
      b.view.maps.depth.view({kH, kW}).narrow(1, kW - 2, 2) / b.view.truth.narrow(1, kW - 2, 2);
  EXPECT_LT((right - 1).abs().max().item<double>(), 1e-3) << "the right edge keeps the view's scale";
}

TEST(DepthAlignment, InsideTheMaskTheCorrectionIsWider) {
  // The mask over the box's left half: its points are not used, and inside it the correction
  // spreads region_factor times wider; far from the mask nothing changes.
  auto aligned = [](double region_factor) {
    BoxView b = box_view(2.0, 0.5, 2, false);
    Image mask(kW, kH, 1, 0.f);
    for (int y = kH / 3; y < 2 * kH / 3; ++y)
      for (int x = kW / 3; x < kW / 2; ++x) mask.at(y, x) = 1.f;
    b.view.input.views[0].mask = mask;
    DepthDetailOptions detail;
    detail.detail = 1;
    detail.region_factor = region_factor;
    align_depth_to_points(b.view.maps, b.view.input, b.points, detail);
    return b.view.maps.depth.view({kH, kW}).clone();
  };
  const torch::Tensor same = aligned(1), wider = aligned(3);
  const int y = kH / 2, x = kW / 3 + 1;  // inside the mask
  EXPECT_GT(std::abs(wider[y][x].item<double>() / same[y][x].item<double>() - 1), 0.02);
  EXPECT_TRUE(torch::allclose(wider.narrow(1, kW - 4, 4), same.narrow(1, kW - 4, 4))) << "far from the mask";
}

TEST(DepthAlignment, ASyntheticScenesPointsComeFromItsDepthMaps) {
  const std::filesystem::path dir = test::synthetic_room("depth-alignment", 4, 32, 8);
  const Scene scene = load_scene(dir);
  PointsOrigin origin;
  const std::vector<Eigen::Vector3d> points = scene_geometry_points(scene, false, &origin);
  EXPECT_EQ(points.size(), 4u * 16u);  // every 8th pixel of 32 x 32, 4 views
  EXPECT_EQ(origin.description, "4 views' depth maps (64 points)");
  EXPECT_EQ(origin.kind, PointsSource::DepthMaps);
  // Each point is at its depth map's depth from its view.
  const std::optional<Image> depth = load_view_depth(scene, scene.views[0]);
  ASSERT_TRUE(depth.has_value());
  const Eigen::Matrix4d w2c = scene.views[0].camera.w2c_opencv();
  const Eigen::Vector3d c = w2c.block<3, 3>(0, 0) * points[0] + w2c.block<3, 1>(0, 3);
  EXPECT_NEAR(c.z(), depth->at(4, 4), 1e-4 * depth->at(4, 4));
  std::filesystem::remove_all(dir / "depth");
  EXPECT_TRUE(scene_geometry_points(load_scene(dir), false, &origin).empty());
  EXPECT_EQ(origin.description, "none");
  EXPECT_EQ(origin.kind, PointsSource::None);
}

TEST(DepthAlignment, WithoutDepthMapsTheScenesPointsAreTriangulatedFromItsPhotos) {
  const std::filesystem::path dir = test::synthetic_room("depth-alignment-photos", 8, 256, 8);
  const Scene with_maps = load_scene(dir);
  const std::optional<Image> truth = load_view_depth(with_maps, with_maps.views[0]);
  ASSERT_TRUE(truth.has_value());
  std::filesystem::remove_all(dir / "depth");
  const Scene scene = load_scene(dir);
  PointsOrigin origin;
  EXPECT_TRUE(scene_geometry_points(scene, false, &origin).empty()) << "only when asked";
  const std::vector<Eigen::Vector3d> points = scene_geometry_points(scene, false, &origin, 8, {0, 1});
  ASSERT_GE(points.size(), 30u) << origin.description;
  EXPECT_EQ(origin.description.rfind("points triangulated from 2 views' photos (", 0), 0u) << origin.description;
  EXPECT_EQ(origin.kind, PointsSource::Photos);
  // The points seen by view 0 lie at its true depth: the median relative error is small.
  const Camera& camera = scene.views[0].camera;
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  std::vector<double> errors;
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d c = w2c.block<3, 3>(0, 0) * p + w2c.block<3, 1>(0, 3);
    if (!(c.z() > 0)) continue;
    const int x = static_cast<int>(camera.K.fx * c.x() / c.z() + camera.K.cx);
    const int y = static_cast<int>(camera.K.fy * c.y() / c.z() + camera.K.cy);
    if (x < 0 || y < 0 || x >= truth->width || y >= truth->height) continue;
    errors.push_back(std::abs(std::log(c.z() / truth->at(y, x))));
  }
  ASSERT_GE(errors.size(), 30u);
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  EXPECT_LT(errors[errors.size() / 2], 0.03) << origin.description;
}

}  // namespace depth_alignment_test
}  // namespace
}  // namespace ii
