// Camera paths, the camera JSON format, and conversions into GaussianSet.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <fstream>

#include "common/files.h"
#include "render/gaussians.h"
#include "camera/trajectory.h"
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
  EXPECT_NE(msg(R"([{"width": 10, "height": 10, "fx": 5, "convention": "dx", "c2w": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}])")
                .find("convention"),
            std::string::npos);
}

TEST(Gaussians, FromSplatCloud) {
  SplatCloud c;
  c.means = {1, 2, 3, 4, 5, 6};
  c.normals.assign(6, 0.f);
  c.sh_dc = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f};
  c.sh_rest_per_channel = 3;  // degree 1, channel-major: R0 R1 R2 G0 G1 G2 B0 B1 B2
  for (int i = 0; i < 2; ++i)
    for (int k = 0; k < 9; ++k) c.sh_rest.push_back(static_cast<float>(100 * i + k));
  c.opacity_logit = {0.f, 2.f};
  c.log_scales = {0, 0, 0, -1, -2, -3};
  c.rotations = {1, 0, 0, 0, 0, 1, 0, 0};
  const GaussianSet g = gaussians_from_splats(c);
  EXPECT_EQ(g.sh_degree, 1);
  ASSERT_EQ(g.colors.sizes(), (std::vector<int64_t>{2, 4, 3}));
  EXPECT_FLOAT_EQ(g.colors[1][0][2].item<float>(), 0.6f);
  EXPECT_FLOAT_EQ(g.colors[1][2][0].item<float>(), 101.f);  // R, coefficient 2 (rest index 1)
  EXPECT_FLOAT_EQ(g.colors[1][1][1].item<float>(), 103.f);  // G, rest index 0
  EXPECT_FLOAT_EQ(g.colors[0][3][2].item<float>(), 8.f);    // B, rest index 2
  EXPECT_NEAR(g.opacities[0].item<float>(), 0.5f, 1e-6);
  EXPECT_NEAR(g.scales[1][2].item<float>(), std::exp(-3.f), 1e-6);
  EXPECT_EQ(gaussians_from_splats(c, 0).colors.size(1), 1);
  EXPECT_EQ(gaussians_from_splats(c, 0).sh_degree, 0);
}

TEST(Gaussians, FromNetworkMaps) {
  GaussianMaps m;
  m.xyz = torch::arange(2 * 3 * 4 * 5, torch::kFloat32).reshape({1, 2, 3, 4, 5});
  m.rgb = m.xyz * 0.01;
  m.rotation = torch::rand({1, 2, 4, 4, 5});
  m.scale = torch::rand({1, 2, 3, 4, 5});
  m.opacity = torch::rand({1, 2, 1, 4, 5});
  const GaussianSet g = gaussians_from_maps(m);
  ASSERT_EQ(g.means.sizes(), (std::vector<int64_t>{40, 3}));
  // Index v*H*W + i*W + j holds pixel (i, j) of view v.
  EXPECT_FLOAT_EQ(g.means[1 * 20 + 2 * 5 + 3][1].item<float>(), m.xyz[0][1][1][2][3].item<float>());
  EXPECT_EQ(g.opacities.dim(), 1);
  EXPECT_EQ(g.sh_degree, -1);
}

}  // namespace
}  // namespace ii
