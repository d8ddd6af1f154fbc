// Points triangulated from a capture's photos with its own cameras: on the fern they lie where
// its COLMAP reconstruction put the scene, the neighbours chosen look the same way, points
// prepared view by view are those of one triangulation, and an unreadable photo is an error naming the file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "common/error.h"
#include "data/masks.h"
#include "data/photo_points.h"
#include "data/scene.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

// The median camera z of the points that view sees.
double median_depth(const Camera& camera, const std::vector<Eigen::Vector3d>& points) {
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  std::vector<double> z;
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d c = w2c.block<3, 3>(0, 0) * p + w2c.block<3, 1>(0, 3);
    const double u = camera.K.fx * c.x() / c.z() + camera.K.cx, v = camera.K.fy * c.y() / c.z() + camera.K.cy;
    if (c.z() > 0 && u >= 0 && v >= 0 && u < camera.K.width && v < camera.K.height) z.push_back(c.z());
  }
  if (z.empty()) return 0;
  std::nth_element(z.begin(), z.begin() + z.size() / 2, z.end());
  return z[z.size() / 2];
}

TEST(PhotoPoints, TheFernsPointsLieWhereItsColmapModelPutTheScene) {
  II_REQUIRE_SHARED(dir, "data/fern");
  const Scene scene = load_scene(dir);
  const std::vector<Eigen::Vector3d> colmap = load_scene_points(scene);
  ASSERT_GT(colmap.size(), 1000u);
  const PhotoPoints photos = triangulate_photo_points(scene, {0, 10});
  EXPECT_EQ(photos.pairs, 4);
  EXPECT_GT(photos.points.size(), 300u);
  EXPECT_LE(static_cast<int>(photos.points.size()), photos.matches);
  for (int v : {0, 10}) {
    const double ours = median_depth(scene.views[static_cast<size_t>(v)].camera, photos.points);
    const double theirs = median_depth(scene.views[static_cast<size_t>(v)].camera, colmap);
    EXPECT_NEAR(ours / theirs, 1.0, 0.1) << "view " << v << ": " << ours << " against COLMAP's " << theirs;
  }
}

TEST(PhotoPoints, NeighboursAreOtherViewsLookingTheSameWay) {
  II_REQUIRE_SHARED(dir, "data/statue");
  const Scene scene = load_scene(dir);
  const std::vector<int> n = triangulation_neighbours(scene, 5, 3);
  ASSERT_EQ(n.size(), 3u);
  for (int j : n) {
    EXPECT_NE(j, 5);
    const Eigen::Vector3d a = -scene.views[5].camera.rotation().col(2), b = -scene.views[static_cast<size_t>(j)].camera.rotation().col(2);
    EXPECT_GT(a.dot(b), std::cos(35.0 * M_PI / 180.0)) << scene.views[static_cast<size_t>(j)].name;
  }
  EXPECT_NE(n[0], n[1]);
  EXPECT_NE(n[1], n[2]);
  EXPECT_NE(n[0], n[2]);
  EXPECT_TRUE(triangulation_neighbours(scene, 5, 3, 0.0).empty()) << "no other view looks exactly the same way";
}

// A copy of the fern's photos and cameras in a folder of its own (new files: nothing kept).
Scene fern_copy(const fs::path& dir, const std::string& tag) {
  const fs::path copy = test::temp_dir(tag) / "fern";
  fs::create_directories(copy);
  fs::copy(dir / "poses_bounds.npy", copy / "poses_bounds.npy");
  fs::copy(dir / "images_8", copy / "images_8");
  return load_scene(copy);
}

// A server prepares every view's points while its page is painted on; an edit's context then
// gathers them: the same points, in the same order, as one triangulation of that set of views.
TEST(PhotoPoints, PointsPreparedBeforehandAreThoseOfTheSetsTriangulation) {
  II_REQUIRE_SHARED(dir, "data/fern");
  const Scene prepared = fern_copy(dir, "photo-points-prepared"), fresh = fern_copy(dir, "photo-points-fresh");
  std::vector<int> all(prepared.views.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  prepare_photo_points(prepared, all);
  const auto gathered = cached_photo_points(prepared, {7, 3, 12});
  const PhotoPoints made = triangulate_photo_points(fresh, {3, 7, 12});
  ASSERT_GT(made.points.size(), 300u);
  EXPECT_EQ(gathered->points, made.points);
  EXPECT_EQ(gathered->matches, made.matches);
  EXPECT_EQ(gathered->pairs, made.pairs);
  // and a view asked again is the same again
  EXPECT_EQ(cached_photo_points(prepared, {3})->points, triangulate_photo_points(fresh, {3}).points);
}

TEST(PhotoPoints, AnUnreadablePhotoIsAnErrorNamingIt) {
  II_REQUIRE_SHARED(dir, "data/fern");
  const Scene scene = fern_copy(dir, "photo-points-bad");
  const fs::path broken = scene.views[0].image_path;
  std::ofstream(broken, std::ios::trunc) << "not an image";
  try {
    triangulate_photo_points(scene, {0});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(broken.string()), std::string::npos) << e.what();
  }
}

// The network's depth is then kept as it is: the prediction goes on, saying why.
TEST(PhotoPoints, AnUnreadablePhotoLeavesTheScenesPointsEmptyAndSaysWhy) {
  II_REQUIRE_SHARED(dir, "data/fern");
  const Scene scene = fern_copy(dir, "photo-points-bad-geometry");
  const fs::path broken = scene.views[0].image_path;
  std::ofstream(broken, std::ios::trunc) << "not an image";
  PointsOrigin origin;
  EXPECT_TRUE(scene_geometry_points(scene, false, &origin, 8, {0}).empty());
  EXPECT_EQ(origin.description.rfind("none (triangulating the photos failed: ", 0), 0u) << origin.description;
  EXPECT_EQ(origin.kind, PointsSource::None);
  EXPECT_NE(origin.description.find(broken.string()), std::string::npos) << origin.description;
}

}  // namespace
}  // namespace ii
