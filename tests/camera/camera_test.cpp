#include <gtest/gtest.h>

#include <cmath>

#include <Eigen/Geometry>

#include "camera/camera.h"
#include "io/safetensors.h"
#include "test_support.h"

namespace ii {
namespace {

// Camera of view v from the fixture's official camera vectors [1, V, 20].
Camera fixture_camera(const std::vector<float>& cams, int v, int width, int height) {
  const float* c = &cams[v * 20];
  Camera cam;
  for (int r = 0; r < 4; ++r)
    for (int k = 0; k < 4; ++k) cam.c2w(r, k) = c[r * 4 + k];
  cam.K = Intrinsics::from_fov(width, height, c[16], c[17]);
  return cam;
}

float max_abs_diff(const std::vector<float>& a, const float* b, size_t n) {
  float m = 0;
  for (size_t i = 0; i < n; ++i) m = std::max(m, std::abs(a[i] - b[i]));
  return m;
}

TEST(CameraParity, RaysAndPluckerMatchOfficialFixture) {
  II_REQUIRE_SHARED(path, "fixtures/official-tiny/io.safetensors");
  const SafetensorsFile io = read_safetensors(path);
  const std::vector<float> cams = io.at("cameras", path).to_float();
  const std::vector<float> ro = io.at("rays_o", path).to_float();
  const std::vector<float> rd = io.at("rays_d", path).to_float();
  const std::vector<float> rdu = io.at("rays_d_un", path).to_float();
  const std::vector<float> pl = io.at("plucker", path).to_float();
  const int V = 4, H = 32, W = 48;
  const size_t n = static_cast<size_t>(H) * W * 3;
  for (int v = 0; v < V; ++v) {
    const Camera cam = fixture_camera(cams, v, W, H);
    const Rays rays = compute_rays(cam);
    EXPECT_LT(max_abs_diff(rays.origin, &ro[v * n], n), 1e-5) << "view " << v;
    EXPECT_LT(max_abs_diff(rays.dir, &rd[v * n], n), 1e-5) << "view " << v;
    EXPECT_LT(max_abs_diff(rays.dir_unnorm, &rdu[v * n], n), 1e-5) << "view " << v;
    const std::vector<float> p = plucker_chw(rays);
    EXPECT_LT(max_abs_diff(p, &pl[v * 6 * H * W], p.size()), 1e-5) << "view " << v;
    // The camera vector rebuilt from our camera is the fixture's.
    const auto vec = cam.official_vector();
    for (int k = 0; k < 20; ++k) EXPECT_NEAR(vec[k], cams[v * 20 + k], 1e-6) << "view " << v << " entry " << k;
  }
}

TEST(Camera, FovIntrinsicsRoundTrip) {
  const Intrinsics K = Intrinsics::from_fov(904, 512, 1.2, 0.8);
  EXPECT_NEAR(K.fov_x(), 1.2, 1e-12);
  EXPECT_NEAR(K.fov_y(), 0.8, 1e-12);
  EXPECT_DOUBLE_EQ(K.cx, 452.0);
  EXPECT_DOUBLE_EQ(K.cy, 256.0);
}

TEST(Camera, CentrePixelLooksDownMinusZ) {
  Camera cam;
  cam.K = Intrinsics::from_fov(3, 3, 1.0, 1.0);
  cam.c2w.block<3, 1>(0, 3) = Eigen::Vector3d(1, 2, 3);
  const Rays r = compute_rays(cam);
  const size_t centre = (1 * 3 + 1) * 3;
  EXPECT_FLOAT_EQ(r.dir[centre + 2], -1.0f);
  EXPECT_FLOAT_EQ(r.dir_unnorm[centre + 2], -1.0f);
  EXPECT_FLOAT_EQ(r.origin[centre + 1], 2.0f);
  // Top-left pixel points up (+y) and left (-x) in an OpenGL camera.
  EXPECT_LT(r.dir[0], 0.f);
  EXPECT_GT(r.dir[1], 0.f);
}

TEST(Camera, ZDepthDirectionsHaveUnitDepth) {
  Camera cam;
  cam.K = {20, 10, 15.0, 17.0, 9.3, 5.2};
  Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  cam.c2w.block<3, 3>(0, 0) = R;
  const Rays r = compute_rays(cam);
  const Eigen::Vector3d forward = -R.col(2);
  for (size_t p = 0; p < r.dir_unnorm.size(); p += 3) {
    const Eigen::Vector3d du(r.dir_unnorm[p], r.dir_unnorm[p + 1], r.dir_unnorm[p + 2]);
    const Eigen::Vector3d d(r.dir[p], r.dir[p + 1], r.dir[p + 2]);
    EXPECT_NEAR(du.dot(forward), 1.0, 1e-6);
    EXPECT_NEAR(d.norm(), 1.0, 1e-6);
    EXPECT_NEAR(du.normalized().dot(d), 1.0, 1e-6);
  }
}

TEST(Camera, CropAndResizeKeepRaysExact) {
  Camera cam;
  cam.K = Intrinsics::from_fov(910, 512, 1.5, 0.9);
  cam.c2w.block<3, 3>(0, 0) = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Camera cropped = cam.cropped(3, 0, 904, 512);
  const Rays full = compute_rays(cam), part = compute_rays(cropped);
  for (int i : {0, 100, 511})
    for (int j : {0, 450, 903})
      for (int a = 0; a < 3; ++a)
        EXPECT_FLOAT_EQ(part.dir[(i * 904 + j) * 3 + a], full.dir[(i * 910 + j + 3) * 3 + a]);
  // Halving the image: the pixel-centre grid shifts, but the field of view is unchanged.
  const Camera half = cam.resized(455, 256);
  EXPECT_NEAR(half.K.fov_x(), cam.K.fov_x(), 1e-12);
  EXPECT_NEAR(half.K.fov_y(), cam.K.fov_y(), 1e-12);
}

TEST(Camera, OpenCvWorldToCameraInvertsPose) {
  Camera cam;
  cam.c2w.block<3, 3>(0, 0) = Eigen::AngleAxisd(1.1, Eigen::Vector3d(0.2, 1, -0.4).normalized()).toRotationMatrix();
  cam.c2w.block<3, 1>(0, 3) = Eigen::Vector3d(0.5, -2, 7);
  const Eigen::Matrix4d w2c = cam.w2c_opencv();
  // A point in front of an OpenGL camera (-z) has positive OpenCV z.
  const Eigen::Vector4d p_cam_gl(0.1, 0.2, -3.0, 1.0);
  const Eigen::Vector4d world = cam.c2w * p_cam_gl;
  const Eigen::Vector4d p_cv = w2c * world;
  EXPECT_NEAR(p_cv.x(), 0.1, 1e-12);
  EXPECT_NEAR(p_cv.y(), -0.2, 1e-12);
  EXPECT_NEAR(p_cv.z(), 3.0, 1e-12);
  EXPECT_TRUE(opencv_to_opengl(opengl_to_opencv(cam.c2w)).isApprox(cam.c2w));
}

TEST(PoseNormalization, CentresFitInUnitCube) {
  std::vector<Camera> cams(3);
  cams[0].c2w.block<3, 1>(0, 3) = Eigen::Vector3d(0, 0, 0);
  cams[1].c2w.block<3, 1>(0, 3) = Eigen::Vector3d(4, 1, 0);
  cams[2].c2w.block<3, 1>(0, 3) = Eigen::Vector3d(2, -2, 6);
  const PoseNormalization n = fit_pose_normalization(cams);
  EXPECT_TRUE(n.mean.isApprox(Eigen::Vector3d(2, -1.0 / 3.0, 2)));
  EXPECT_DOUBLE_EQ(n.scale, 4.0);  // |6 - 2| on z
  const Camera c = n.apply(cams[2]);
  EXPECT_NEAR(c.center().z(), 1.0, 1e-12);
  EXPECT_TRUE(c.rotation().isApprox(cams[2].rotation()));
}

TEST(PoseNormalization, SingleCameraKeepsUnitScale) {
  const PoseNormalization n = fit_pose_normalization({Camera{}});
  EXPECT_DOUBLE_EQ(n.scale, 1.0);
  EXPECT_EQ(test::error_message([] { fit_pose_normalization({}); }),
            "pose normalisation needs at least one camera");
}

}  // namespace
}  // namespace ii
