// nerfstudio / instant-ngp transforms.json reader: the real fox scene, the format's
// variants, and bad input with its exact message.
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <fstream>

#include "data/scene.h"
#include "data/scene_readers.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

TEST(NerfstudioScene, FoxGoldenValues) {
  II_REQUIRE_SHARED(dir, "data/fox");
  const Scene s = load_scene(dir);
  EXPECT_EQ(s.format, "nerfstudio");
  // All 67 listed frames have their image in the shared copy (PROVENANCE.md).
  ASSERT_EQ(s.views.size(), 67u);
  EXPECT_TRUE(s.warnings.empty());
  EXPECT_EQ(s.views.front().name, "0001");
  EXPECT_EQ(s.views.back().name, "0115");
  EXPECT_EQ(s.views.front().image_path, dir / "images" / "0001.jpg");
  for (const View& v : s.views) {
    const Intrinsics& K = v.camera.K;
    EXPECT_EQ(K.width, 540);
    EXPECT_EQ(K.height, 960);
    EXPECT_DOUBLE_EQ(K.fx, 687.76);
    EXPECT_DOUBLE_EQ(K.fy, 687.245);
    EXPECT_DOUBLE_EQ(K.cx, 277.279);
    EXPECT_DOUBLE_EQ(K.cy, 482.634);
    // OpenCV order k1, k2, p1, p2, k3.
    EXPECT_EQ(v.distortion.coeffs, (std::array<double, 5>{0.0578421, -0.0805099, -0.000980296, 0.00015575, 0}));
    EXPECT_NEAR(v.camera.rotation().determinant(), 1.0, 1e-5);  // as stored: 1e-6 off
  }
  // transform_matrix is taken as is (already OpenGL camera-to-world).
  const Eigen::Matrix4d& first = s.views.front().camera.c2w;
  EXPECT_EQ(first(0, 0), 0.8926439112348871);
  EXPECT_EQ(first(1, 2), -0.8940689141475064);
  EXPECT_EQ(first(0, 3), 3.168359405609479);
  EXPECT_EQ(first(2, 3), -0.9791660699008925);
  EXPECT_EQ(s.views.back().camera.c2w(1, 3), 0.8029906118159125);
  EXPECT_FALSE(s.near.has_value());

  // Loading undistorts: same size, pixels moved near the borders, centre untouched.
  const Image raw = read_image_rgb(s.views[0].image_path);
  const Image img = load_view_image(s.views[0]);
  ASSERT_EQ(img.width, 540);
  ASSERT_EQ(img.height, 960);
  double border_diff = 0;
  for (int i = 0; i < 960; ++i) border_diff += std::abs(img.at(i, 5, 1) - raw.at(i, 5, 1));
  EXPECT_GT(border_diff / 960, 0.005);
  EXPECT_NEAR(img.at(482, 277, 0), raw.at(482, 277, 0), 0.02);
}

fs::path write_transforms(const std::string& json) {
  const fs::path dir = test::temp_dir("ns");
  std::ofstream(dir / "transforms.json") << json;
  return dir;
}

void write_image(const fs::path& p, int w, int h) {
  fs::create_directories(p.parent_path());
  write_png(p, Image(w, h, 3, 0.5f));
}

const char* kIdentity = "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]";

TEST(NerfstudioScene, PerFrameIntrinsicsOverrideGlobalOnes) {
  const fs::path dir = write_transforms(fmt::format(R"({{
    "fl_x": 100, "fl_y": 110, "cx": 40, "cy": 30, "w": 80, "h": 60, "k1": 0.1,
    "frames": [
      {{"file_path": "images/z.png", "transform_matrix": {0}}},
      {{"file_path": "images/a.png", "transform_matrix": {0}, "fl_x": 50, "fl_y": 55, "cx": 41, "cy": 29, "k1": 0, "p2": 0.01}}
    ]}})",
                                                    kIdentity));
  write_image(dir / "images" / "z.png", 80, 60);
  write_image(dir / "images" / "a.png", 80, 60);
  const Scene s = load_scene(dir);
  ASSERT_EQ(s.views.size(), 2u);
  EXPECT_EQ(s.views[0].name, "z");  // file order, not sorted
  EXPECT_EQ(s.views[1].name, "a");
  EXPECT_DOUBLE_EQ(s.views[0].camera.K.fx, 100);
  EXPECT_DOUBLE_EQ(s.views[0].camera.K.fy, 110);
  EXPECT_EQ(s.views[0].distortion.coeffs, (std::array<double, 5>{0.1, 0, 0, 0, 0}));
  EXPECT_DOUBLE_EQ(s.views[1].camera.K.fx, 50);
  EXPECT_DOUBLE_EQ(s.views[1].camera.K.fy, 55);
  EXPECT_DOUBLE_EQ(s.views[1].camera.K.cx, 41);
  EXPECT_DOUBLE_EQ(s.views[1].camera.K.cy, 29);
  EXPECT_EQ(s.views[1].distortion.coeffs, (std::array<double, 5>{0, 0, 0, 0.01, 0}));
  EXPECT_EQ(s.views[1].camera.c2w, Eigen::Matrix4d::Identity());
}

TEST(NerfstudioScene, BlenderStyleAnglesPathsWithoutExtensionAndBackslashes) {
  // NeRF-synthetic: only camera_angle_x, "./train/r_0" without extension, no w/h (taken
  // from the image), 3x4 matrices; a Windows export with backslashes.
  const double angle = 0.6911112070083618;
  const fs::path dir = write_transforms(fmt::format(R"({{"camera_angle_x": {}, "frames": [
      {{"file_path": "./train/r_0", "transform_matrix": [[1,0,0,1],[0,1,0,2],[0,0,1,3]]}},
      {{"file_path": "train\\r_1.png", "transform_matrix": {}}}]}})",
                                                    angle, kIdentity));
  write_image(dir / "train" / "r_0.png", 40, 20);
  write_image(dir / "train" / "r_1.png", 40, 20);
  const Scene s = load_scene(dir);
  ASSERT_EQ(s.views.size(), 2u);
  EXPECT_EQ(s.views[0].image_path, dir / "./train/r_0.png");
  EXPECT_EQ(s.views[1].image_path, dir / "train/r_1.png");
  EXPECT_EQ(s.views[0].name, "r_0");
  const Intrinsics& K = s.views[0].camera.K;
  EXPECT_EQ(K.width, 40);
  EXPECT_EQ(K.height, 20);
  EXPECT_DOUBLE_EQ(K.fx, 40 / (2 * std::tan(angle / 2)));
  EXPECT_DOUBLE_EQ(K.fy, K.fx);  // square pixels when only one angle is given
  EXPECT_DOUBLE_EQ(K.cx, 20);
  EXPECT_DOUBLE_EQ(K.cy, 10);
  EXPECT_EQ(s.views[0].camera.center(), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(s.views[0].camera.c2w.row(3), Eigen::RowVector4d(0, 0, 0, 1));
  EXPECT_FALSE(s.views[0].distortion.any());

  // camera_angle_y gives fy on its own.
  const fs::path dir2 = write_transforms(fmt::format(
      R"({{"camera_angle_x": 1.0, "camera_angle_y": 0.5, "frames": [{{"file_path": "a.png", "transform_matrix": {}}}]}})",
      kIdentity));
  write_image(dir2 / "a.png", 40, 20);
  const Scene s2 = load_scene(dir2);
  EXPECT_DOUBLE_EQ(s2.views[0].camera.K.fy, 20 / (2 * std::tan(0.25)));
}

TEST(NerfstudioScene, SmallerImagesScaleIntrinsics) {
  // Intrinsics for 80x60, files at half size (nerfstudio's images_2 holds the same names).
  const fs::path dir = write_transforms(fmt::format(
      R"({{"fl_x": 100, "fl_y": 110, "cx": 40, "cy": 30, "w": 80, "h": 60, "frames": [{{"file_path": "images/a.png", "transform_matrix": {}}}]}})",
      kIdentity));
  write_image(dir / "images" / "a.png", 80, 60);
  write_image(dir / "images_2" / "a.png", 40, 30);
  SceneOptions o;
  o.image_folder = "images_2";
  const Scene s = load_scene(dir, o);
  ASSERT_EQ(s.views.size(), 1u);
  EXPECT_EQ(s.views[0].image_path, dir / "images_2" / "a.png");
  const Intrinsics& K = s.views[0].camera.K;
  EXPECT_EQ(K.width, 40);
  EXPECT_DOUBLE_EQ(K.fx, 50);
  EXPECT_DOUBLE_EQ(K.fy, 55);
  EXPECT_DOUBLE_EQ(K.cx, 20);
  EXPECT_DOUBLE_EQ(K.cy, 15);
  EXPECT_TRUE(s.warnings.empty());
}

TEST(NerfstudioScene, MissingFramesAreSkippedWithAWarning) {
  const fs::path dir = write_transforms(fmt::format(R"({{"fl_x": 10, "frames": [
      {{"file_path": "a.png", "transform_matrix": {0}}},
      {{"file_path": "gone.png", "transform_matrix": {0}}},
      {{"file_path": "b.png", "transform_matrix": {0}}},
      {{"file_path": "gone2.png", "transform_matrix": {0}}}]}})",
                                                    kIdentity));
  write_image(dir / "a.png", 8, 8);
  write_image(dir / "b.png", 8, 8);
  const Scene s = load_scene(dir);
  ASSERT_EQ(s.views.size(), 2u);
  EXPECT_EQ(s.views[1].name, "b");
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_EQ(s.warnings[0], (dir / "transforms.json").string() + ": 2 of 4 frames have no image file and were skipped (first: " +
                               (dir / "gone.png").string() + ")");
}

TEST(NerfstudioScene, ScaledRotationIsOrthonormalisedWithAWarning) {
  const fs::path dir = write_transforms(
      R"({"fl_x": 10, "frames": [{"file_path": "a.png", "transform_matrix": [[2,0,0,0],[0,2,0,0],[0,0,2,5],[0,0,0,1]]}]})");
  write_image(dir / "a.png", 8, 8);
  const Scene s = load_scene(dir);
  EXPECT_TRUE(s.views[0].camera.rotation().isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  EXPECT_EQ(s.views[0].camera.center(), Eigen::Vector3d(0, 0, 5));
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("frame 0: rotation was not orthonormal"), std::string::npos);
}

// Message of loading a transforms.json with `json` (and an image a.png), after the file name.
std::string error_for(const std::string& json) {
  const fs::path dir = write_transforms(json);
  write_image(dir / "a.png", 8, 8);
  const std::string msg = test::error_message([&] { load_scene(dir); });
  const std::string prefix = (dir / "transforms.json").string() + ": ";
  EXPECT_EQ(msg.rfind(prefix, 0), 0u) << msg;
  return msg.substr(std::min(msg.size(), prefix.size()));
}

std::string frame(const std::string& extra, const std::string& matrix = kIdentity) {
  return R"({"file_path": "a.png", "transform_matrix": )" + matrix + extra + "}";
}

TEST(NerfstudioScene, BadInputIsAClearError) {
  EXPECT_EQ(error_for(R"({"frames": [)").rfind("invalid JSON: [json.exception.parse_error.101] parse error at line 1", 0), 0u);
  EXPECT_EQ(error_for("[1, 2]"), "must hold a JSON object");
  EXPECT_EQ(error_for("{}"), "has no frames");
  EXPECT_EQ(error_for(R"({"frames": []})"), "has no frames");
  EXPECT_EQ(error_for(R"({"frames": {"a": 1}})"), "has no frames");
  EXPECT_EQ(error_for(R"({"fl_x": 10, "frames": [{"file_path": "a.png"}]})"), "frame 0 needs file_path and transform_matrix");
  EXPECT_EQ(error_for(R"({"fl_x": 10, "frames": [7]})"), "frame 0 needs file_path and transform_matrix");
  EXPECT_EQ(error_for(R"({"frames": [)" + frame("") + "]}"),
            "frame 0: no focal length (fl_x, fl_y, camera_angle_x or camera_angle_y)");
  EXPECT_EQ(error_for(R"({"fl_x": "500", "frames": [)" + frame("") + "]}"), "'fl_x' must be a number, got \"500\"");
  EXPECT_EQ(error_for(R"({"fl_x": 10, "frames": [)" + frame(R"(, "cx": [1])") + "]}"),
            "frame 0: 'cx' must be a number, got [1]");
  EXPECT_EQ(error_for(R"({"fl_x": 10, "frames": [)" + frame("", "[[1,0,0,0],[0,1,0,0]]") + "]}"),
            "frame 0: transform_matrix must be a 4x4 (or 3x4) array");
  EXPECT_EQ(error_for(R"({"fl_x": 10, "frames": [)" + frame("", "[[1,0,0,0],[0,1,0,0],[0,0,1,\"x\"]]") + "]}"),
            "frame 0: transform_matrix holds a non-number");
  EXPECT_EQ(error_for(R"({"fl_x": 10, "frames": [)" + frame("", "[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,1,1]]") + "]}"),
            "frame 0: transform_matrix's last row must be 0 0 0 1");
  EXPECT_EQ(error_for(R"({"fl_x": 10, "frames": [)" + frame("", "[[1,0,0,0],[0,1,0,0],[0,0,0,0]]") + "]}"),
            "frame 0: transform_matrix has no valid rotation");
  EXPECT_EQ(error_for(R"({"fl_x": 10, "frames": [)" + frame("", "[[1,0,0,1e999],[0,1,0,0],[0,0,1,0]]") + "]}"),
            "invalid JSON: [json.exception.out_of_range.406] number overflow parsing '1e999'");  // JSON has no inf
  EXPECT_EQ(error_for(R"({"fl_x": 10, "camera_model": "OPENCV_FISHEYE", "frames": [)" + frame("") + "]}"),
            "frame 0: unsupported camera_model OPENCV_FISHEYE (supported: PINHOLE, OPENCV)");
  EXPECT_EQ(error_for(R"({"fl_x": 10, "is_fisheye": true, "frames": [)" + frame("") + "]}"),
            "frame 0: fisheye cameras are not supported");
  EXPECT_EQ(error_for(R"({"fl_x": 10, "k4": 0.01, "frames": [)" + frame("") + "]}"),
            "frame 0: distortion k4 (r^8 term) is not supported");
  EXPECT_EQ(error_for(R"({"fl_x": 10, "w": -8, "frames": [)" + frame("") + "]}"), "frame 0: image size -8x8 is not plausible");

  const fs::path dir = write_transforms(fmt::format(
      R"({{"fl_x": 10, "frames": [{{"file_path": "nope.png", "transform_matrix": {0}}}, {{"file_path": "nope2", "transform_matrix": {0}}}]}})",
      kIdentity));
  EXPECT_EQ(test::error_message([&] { load_scene(dir); }), (dir / "transforms.json").string() +
                                                               ": none of its 2 frames has an image file (first: " +
                                                               (dir / "nope.png").string() + ")");
  const fs::path no_file = test::temp_dir("ns-none");
  EXPECT_EQ(test::error_message([&] { load_nerfstudio_scene(no_file, {}); }).rfind((no_file / "transforms.json").string(), 0),
            0u);
}

}  // namespace
}  // namespace ii
