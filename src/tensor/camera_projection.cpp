#include "tensor/camera_projection.h"

namespace ii {

std::pair<torch::Tensor, torch::Tensor> rotation_and_translation(const Eigen::Matrix4d& m,
                                                                 const torch::TensorOptions& options) {
  Eigen::Matrix<double, 3, 4, Eigen::RowMajor> top = m.topRows<3>();  // [R | t], row by row
  const torch::Tensor rt = torch::from_blob(top.data(), {3, 4}, torch::kFloat64).to(options, false, /*copy=*/true);
  return {rt.narrow(1, 0, 3), rt.select(1, 3)};
}

torch::Tensor transformed(const Eigen::Matrix4d& m, const torch::Tensor& points) {
  const auto [R, t] = rotation_and_translation(m, points.options());
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

}  // namespace ii
