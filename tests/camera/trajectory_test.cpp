// Camera paths and the camera-list JSON format.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>

#include "camera/trajectory.h"
#include "common/files.h"
#include "test_support.h"

namespace ii {
namespace {

Intrinsics square(int size) { return Intrinsics::from_fov(size, size, 1.0, 1.0); }

Camera camera_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  Camera c;
  c.K = square(64);
  c.c2w = look_at(eye, target, Eigen::Vector3d::UnitY());
  return c;
}

TEST(Trajectory, LookAtLooksAtTheTarget) {
  const Eigen::Matrix4d m = look_at({1, 2, 3}, {0, 0.5, -1}, Eigen::Vector3d::UnitY());
  const Eigen::Vector3d forward = -m.block<3, 1>(0, 2);
  EXPECT_NEAR(forward.dot((Eigen::Vector3d(0, 0.5, -1) - Eigen::Vector3d(1, 2, 3)).normalized()), 1.0, 1e-12);
  const Eigen::Matrix3d R = m.topLeftCorner(3, 3);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  EXPECT_GT(R.col(1).dot(Eigen::Vector3d::UnitY()), 0);  // camera up is world up-ish
}

TEST(Trajectory, OfficialOrbit) {
  std::vector<Camera> train = {camera_at({-1, 0, 4}, {0, 0, 0}), camera_at({0, 0.2, 4}, {0, 0, 0}),
                               camera_at({1, 0, 4}, {0, 0, 0})};
  const Eigen::Vector3d centre = train[1].center();
  const auto path = orbit_path(train, centre, 0.5, 72, square(32));
  ASSERT_EQ(path.size(), 72u);
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (const Camera& c : train) n -= c.rotation().col(2);
  n.normalize();
  for (const Camera& c : path) {
    EXPECT_NEAR((c.center() - centre).norm(), 0.5, 1e-12);
    EXPECT_NEAR((c.center() - centre).dot(n), 0.0, 1e-12);  // in the plane normal to n
    EXPECT_TRUE(c.rotation().isApprox(train[1].rotation()));  // nearest camera's rotation
    EXPECT_EQ(c.K.width, 32);
  }
  // First pose along u = n x z.
  const Eigen::Vector3d u = n.cross(Eigen::Vector3d::UnitZ()).normalized();
  EXPECT_TRUE((path[0].center() - centre).normalized().isApprox(u, 1e-9));
}

TEST(Trajectory, SmoothPathPassesThroughTheKeys) {
  std::vector<Camera> keys = {camera_at({-1, 0, 4}, {0, 0, 0}), camera_at({0, 0.5, 3}, {0, 0, 0}),
                              camera_at({1, 0, 4}, {0, 0.2, 0}), camera_at({2, -0.3, 3.5}, {0, 0, 0})};
  const auto path = smooth_path(keys, 7, square(16));  // frames 0, 2, 4, 6 sit on the keys
  ASSERT_EQ(path.size(), 7u);
  for (int k = 0; k < 4; ++k) {
    EXPECT_TRUE(path[2 * k].center().isApprox(keys[k].center(), 1e-12)) << k;
    EXPECT_TRUE(path[2 * k].rotation().isApprox(keys[k].rotation(), 1e-9)) << k;
  }
  for (const Camera& c : path) EXPECT_NEAR(c.rotation().determinant(), 1.0, 1e-9);
  EXPECT_EQ(smooth_path({keys[0]}, 3, square(16)).size(), 3u);
}

TEST(Trajectory, Turntable) {
  const Eigen::Vector3d target(0.5, -1, 2), up(0, -1, 0);
  const auto path = turntable_path(target, 3.0, 30.0, up, 12, square(16));
  ASSERT_EQ(path.size(), 12u);
  for (const Camera& c : path) {
    EXPECT_NEAR((c.center() - target).norm(), 3.0, 1e-12);
    EXPECT_NEAR((c.center() - target).normalized().dot(up), 0.5, 1e-12);  // 30 degrees up
    EXPECT_NEAR((-c.rotation().col(2)).dot((target - c.center()).normalized()), 1.0, 1e-12);
  }
}

TEST(CameraJson, RoundTripAndForms) {
  const auto dir = test::temp_dir("camjson");
  std::vector<NamedCamera> cams = {{"a", camera_at({1, 2, 3}, {0, 0, 0})}, {"b", camera_at({-1, 0, 2}, {0, 1, 0})}};
  cams[1].camera.K.cx = 10.5;
  write_camera_json(dir / "c.json", cams);
  const auto back = read_camera_json(dir / "c.json");
  ASSERT_EQ(back.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(back[i].name, cams[i].name);
    EXPECT_TRUE(back[i].camera.c2w.isApprox(cams[i].camera.c2w, 1e-12));
    EXPECT_DOUBLE_EQ(back[i].camera.K.fx, cams[i].camera.K.fx);
    EXPECT_DOUBLE_EQ(back[i].camera.K.cx, cams[i].camera.K.cx);
  }

  // A bare list, field of view instead of focal lengths, OpenCV axes, w2c.
  write_file_atomic(dir / "d.json", R"([{"width": 100, "height": 50, "fov_y_deg": 90, "convention": "opencv",
      "w2c": [[1,0,0,-1],[0,1,0,-2],[0,0,1,-3]]}])");
  const auto d = read_camera_json(dir / "d.json");
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].name, "0000");
  EXPECT_NEAR(d[0].camera.K.fy, 25.0, 1e-9);
  EXPECT_NEAR(d[0].camera.K.fx, 25.0, 1e-9);
  EXPECT_DOUBLE_EQ(d[0].camera.K.cx, 50.0);
  EXPECT_TRUE(d[0].camera.center().isApprox(Eigen::Vector3d(1, 2, 3)));
  EXPECT_TRUE(d[0].camera.w2c_opencv().isApprox(
      (Eigen::Matrix4d() << 1, 0, 0, -1, 0, 1, 0, -2, 0, 0, 1, -3, 0, 0, 0, 1).finished()));
}

TEST(CameraJson, ErrorsNameTheProblem) {
  const auto dir = test::temp_dir("camjson-bad");
  auto msg = [&](const std::string& text) {
    write_file_atomic(dir / "x.json", text);
    return test::error_message([&] { read_camera_json(dir / "x.json"); });
  };
  EXPECT_NE(msg("{").find("not valid JSON"), std::string::npos);
  EXPECT_NE(msg(R"([{"width": 10, "height": 10, "fx": 5}])").find("c2w"), std::string::npos);
  EXPECT_NE(msg(R"([{"width": 10, "height": 10, "c2w": [[1,0,0,0]]}])").find("fx"), std::string::npos);
  EXPECT_NE(msg(R"([{"width": 10, "height": 10, "fx": 5, "c2w": [[1,0,0],[0,1,0],[0,0,1]]}])").find("row 0"),
            std::string::npos);
  EXPECT_NE(msg(R"({"cameras": [{"name": 3, "width": 10}]})").find("x.json"), std::string::npos);
  // Found by fuzzing: a width beyond int was converted anyway (undefined behaviour).
  EXPECT_EQ(msg(R"([{"width": 7777770010, "height": 8, "fx": 5, "c2w": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}])"),
            (dir / "x.json").string() +
                ": camera 0 ('0000'): 'width' must be a whole number of pixels from 1 to 1048576, not 7777770010");
  EXPECT_EQ(msg(R"([{"width": 10, "height": 2.5, "fx": 5, "c2w": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}])"),
            (dir / "x.json").string() +
                ": camera 0 ('0000'): 'height' must be a whole number of pixels from 1 to 1048576, not 2.5");
  EXPECT_NE(msg(R"([{"width": 10, "height": 10, "fx": 5, "convention": "dx", "c2w": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}])")
                .find("convention"),
            std::string::npos);
}

TEST(Trajectory, CameraSizesAndOrbitCentre) {
  const Intrinsics K = intrinsics_fov_y(64, 32, M_PI / 2);
  EXPECT_DOUBLE_EQ(K.fy, 16.0);  // 32 / (2 tan 45 deg)
  EXPECT_DOUBLE_EQ(K.fx, 16.0);
  EXPECT_DOUBLE_EQ(K.cx, 32.0);
  Camera c;
  c.K = {40, 20, 30, 30, 20, 10};
  EXPECT_EQ(resized_to(c, 0, 0).K.width, 40);
  EXPECT_EQ(resized_to(c, 0, 10).K.width, 20);  // the aspect ratio kept
  EXPECT_EQ(resized_to(c, 80, 0).K.height, 40);
  EXPECT_DOUBLE_EQ(resized_to(c, 80, 0).K.fx, 60.0);
  std::vector<Camera> cams(3, c);
  cams[0].c2w(0, 3) = -3;
  cams[1].c2w(0, 3) = 0.5;  // nearest to the mean x = 0
  cams[2].c2w(0, 3) = 2.5;
  EXPECT_EQ(central_camera_position(cams).x(), 0.5);
  // A turntable around a sphere keeps it in view: every camera at the same distance.
  const Eigen::Vector3d centre(1, 2, 3);
  for (const Camera& t : turntable_around_sphere(centre, 1.0, M_PI / 3, 20, Eigen::Vector3d::UnitY(), 4, 32, 32))
    EXPECT_NEAR((t.center() - centre).norm(), 2.0, 1e-9);  // 1 / sin(30 deg)
}

}  // namespace
}  // namespace ii
