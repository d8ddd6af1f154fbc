#include "camera/camera.h"

#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/LU>

#include "common/error.h"

namespace ii {

Intrinsics Intrinsics::from_fov(int width, int height, double fov_x, double fov_y) {
  Intrinsics K;
  K.width = width;
  K.height = height;
  K.fx = width / (2.0 * std::tan(fov_x / 2.0));
  K.fy = height / (2.0 * std::tan(fov_y / 2.0));
  K.cx = width / 2.0;
  K.cy = height / 2.0;
  return K;
}

double Intrinsics::fov_x() const { return 2.0 * std::atan(width / (2.0 * fx)); }
double Intrinsics::fov_y() const { return 2.0 * std::atan(height / (2.0 * fy)); }

bool Distortion::any() const {
  for (double c : coeffs)
    if (c != 0.0) return true;
  return false;
}

Eigen::Matrix4d opencv_to_opengl(const Eigen::Matrix4d& c2w) {
  Eigen::Matrix4d m = c2w;
  m.block<3, 1>(0, 1) *= -1.0;
  m.block<3, 1>(0, 2) *= -1.0;
  return m;
}

Eigen::Matrix4d opengl_to_opencv(const Eigen::Matrix4d& c2w) { return opencv_to_opengl(c2w); }

Eigen::Matrix4d Camera::w2c_opencv() const {
  // Rigid inverse: exact and cheaper than a general inverse.
  const Eigen::Matrix4d cv = opengl_to_opencv(c2w);
  Eigen::Matrix4d w2c = Eigen::Matrix4d::Identity();
  const Eigen::Matrix3d Rt = cv.block<3, 3>(0, 0).transpose();
  w2c.block<3, 3>(0, 0) = Rt;
  w2c.block<3, 1>(0, 3) = -Rt * cv.block<3, 1>(0, 3);
  return w2c;
}

std::array<float, 20> Camera::official_vector() const {
  std::array<float, 20> v{};
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) v[r * 4 + c] = static_cast<float>(c2w(r, c));
  v[16] = static_cast<float>(K.fov_x());
  v[17] = static_cast<float>(K.fov_y());
  v[18] = 0.5f;
  v[19] = 0.5f;
  return v;
}

Camera Camera::resized(int new_width, int new_height) const {
  Camera out = *this;
  const double sx = static_cast<double>(new_width) / K.width;
  const double sy = static_cast<double>(new_height) / K.height;
  out.K.width = new_width;
  out.K.height = new_height;
  out.K.fx *= sx;
  out.K.cx *= sx;
  out.K.fy *= sy;
  out.K.cy *= sy;
  return out;
}

Camera Camera::cropped(int x0, int y0, int new_width, int new_height) const {
  Camera out = *this;
  out.K.width = new_width;
  out.K.height = new_height;
  out.K.cx -= x0;
  out.K.cy -= y0;
  return out;
}

Rays compute_rays(const Camera& camera) {
  const Intrinsics& K = camera.K;
  Rays rays;
  rays.width = K.width;
  rays.height = K.height;
  const size_t n = static_cast<size_t>(K.width) * K.height * 3;
  rays.origin.resize(n);
  rays.dir.resize(n);
  rays.dir_unnorm.resize(n);
  const Eigen::Matrix3d R = camera.rotation();
  const Eigen::Vector3d o = camera.center();
  for (int i = 0; i < K.height; ++i) {
    // OpenGL camera frame: +y is up, so image rows (growing downwards) map to -y.
    const double v = -((i + 0.5) - K.cy) / K.fy;
    for (int j = 0; j < K.width; ++j) {
      const double u = ((j + 0.5) - K.cx) / K.fx;
      const Eigen::Vector3d d_un = R * Eigen::Vector3d(u, v, -1.0);
      const Eigen::Vector3d d = d_un / std::sqrt(u * u + v * v + 1.0);
      const size_t k = (static_cast<size_t>(i) * K.width + j) * 3;
      for (int a = 0; a < 3; ++a) {
        rays.origin[k + a] = static_cast<float>(o[a]);
        rays.dir[k + a] = static_cast<float>(d[a]);
        rays.dir_unnorm[k + a] = static_cast<float>(d_un[a]);
      }
    }
  }
  return rays;
}

std::vector<float> plucker_chw(const Rays& rays) {
  const size_t hw = static_cast<size_t>(rays.width) * rays.height;
  std::vector<float> out(6 * hw);
  for (size_t p = 0; p < hw; ++p) {
    const float* o = &rays.origin[p * 3];
    const float* d = &rays.dir[p * 3];
    const float m[3] = {o[1] * d[2] - o[2] * d[1], o[2] * d[0] - o[0] * d[2],
                        o[0] * d[1] - o[1] * d[0]};
    for (int a = 0; a < 3; ++a) {
      out[a * hw + p] = d[a];
      out[(3 + a) * hw + p] = m[a];
    }
  }
  return out;
}

Camera PoseNormalization::apply(const Camera& camera) const {
  Camera out = camera;
  out.c2w.block<3, 1>(0, 3) = apply(camera.center());
  return out;
}

PoseNormalization fit_pose_normalization(const std::vector<Camera>& cameras) {
  if (cameras.empty()) fail("pose normalisation needs at least one camera");
  PoseNormalization n;
  for (const Camera& c : cameras) n.mean += c.center();
  n.mean /= static_cast<double>(cameras.size());
  double s = 0.0;
  for (const Camera& c : cameras) s = std::max(s, (c.center() - n.mean).cwiseAbs().maxCoeff());
  // A single camera (or identical centres) has no extent: keep the scale at 1.
  n.scale = s > 0.0 ? s : 1.0;
  return n;
}

}  // namespace ii
