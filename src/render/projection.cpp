#include "render/projection.h"

#include <Eigen/LU>

namespace ii {

torch::Tensor transformed(const Eigen::Matrix4d& m, const torch::Tensor& points) {
  torch::Tensor R = torch::empty({3, 3}, torch::kFloat64), t = torch::empty({3}, torch::kFloat64);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R[r][c] = m(r, c);
    t[r] = m(r, 3);
  }
  return points.matmul(R.t()) + t;
}

PixelHit project(const Camera& camera, const torch::Tensor& points) {
  const torch::Tensor p = transformed(camera.w2c_opencv(), points);
  const Intrinsics& K = camera.K;
  PixelHit hit;
  hit.z = p.select(1, 2);
  const torch::Tensor u = p.select(1, 0) / hit.z.clamp_min(1e-9) * K.fx + K.cx;
  const torch::Tensor v = p.select(1, 1) / hit.z.clamp_min(1e-9) * K.fy + K.cy;
  hit.inside = (hit.z > 0).logical_and(u >= 0).logical_and(v >= 0).logical_and(u < K.width).logical_and(v < K.height);
  hit.index = v.clamp(0, K.height - 1).to(torch::kLong) * K.width + u.clamp(0, K.width - 1).to(torch::kLong);
  return hit;
}

torch::Tensor unproject(const Camera& camera, const torch::Tensor& v, const torch::Tensor& u, const torch::Tensor& z) {
  const Intrinsics& K = camera.K;
  const torch::Tensor vd = v.to(torch::kFloat64), ud = u.to(torch::kFloat64), zd = z.to(torch::kFloat64);
  const torch::Tensor local = torch::stack({(ud + 0.5 - K.cx) / K.fx * zd, (vd + 0.5 - K.cy) / K.fy * zd, zd}, 1);
  return transformed(camera.w2c_opencv().inverse(), local);
}

}  // namespace ii
