#include "geometry/surface_splats.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <vector>

#include "common/error.h"

namespace ii {

GaussianSet surface_gaussians(const Camera& camera, const torch::Tensor& depth, const torch::Tensor& take,
                              const Image& colour, float opacity, double width) {
  const int h = camera.K.height, w = camera.K.width;
  if (depth.dim() != 2 || depth.size(0) != h || depth.size(1) != w || take.sizes() != depth.sizes())
    fail("surface_gaussians: depth and take must be the camera's size ({}x{})", w, h);
  if (colour.width != w || colour.height != h || colour.channels < 3)
    fail("surface_gaussians: the colour picture is {}x{}, the camera {}x{}", colour.width, colour.height, w, h);
  const torch::Tensor d = depth.to(torch::kCPU, torch::kFloat32).contiguous();
  const torch::Tensor t = take.to(torch::kCPU, torch::kBool).contiguous();
  const float* dp = d.data_ptr<float>();
  const bool* tp = t.data_ptr<bool>();
  const Rays rays = compute_rays(camera);
  const Eigen::Matrix3d axes = camera.rotation();
  auto valid = [&](int y, int x) {
    return x >= 0 && y >= 0 && x < w && y < h && std::isfinite(dp[y * w + x]) && dp[y * w + x] > 0;
  };
  auto point = [&](int y, int x) {
    const size_t i = static_cast<size_t>(y) * w + x;
    const Eigen::Vector3d o(rays.origin[3 * i], rays.origin[3 * i + 1], rays.origin[3 * i + 2]);
    const Eigen::Vector3d dir(rays.dir_unnorm[3 * i], rays.dir_unnorm[3 * i + 1], rays.dir_unnorm[3 * i + 2]);
    return Eigen::Vector3d(o + static_cast<double>(dp[i]) * dir);
  };
  // The step to the neighbouring pixels' points along one image axis; a camera-facing step of
  // one pixel's footprint where there is no neighbour or the depth jumps.
  auto step = [&](int y, int x, int dy, int dx, const Eigen::Vector3d& fallback) {
    const bool ahead = valid(y + dy, x + dx), behind = valid(y - dy, x - dx);
    Eigen::Vector3d s = fallback;
    if (ahead && behind) s = (point(y + dy, x + dx) - point(y - dy, x - dx)) / 2;
    else if (ahead) s = point(y + dy, x + dx) - point(y, x);
    else if (behind) s = point(y, x) - point(y - dy, x - dx);
    return s.norm() > 4 * fallback.norm() ? fallback : s;
  };
  std::vector<float> means, scales, quats, opacities, colours;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (!tp[y * w + x] || !valid(y, x)) continue;
      const double z = dp[y * w + x];
      const Eigen::Vector3d p = point(y, x);
      const Eigen::Vector3d du = step(y, x, 0, 1, axes.col(0) * (z / camera.K.fx));
      const Eigen::Vector3d dv = step(y, x, 1, 0, -axes.col(1) * (z / camera.K.fy));
      Eigen::Vector3d n = du.cross(dv);
      if (n.norm() < 1e-12 * du.norm() * dv.norm() || n.norm() == 0) n = axes.col(2);
      n.normalize();
      const Eigen::Vector3d a = du.normalized(), b = n.cross(a);
      Eigen::Matrix3d r;
      r.col(0) = a;
      r.col(1) = b;
      r.col(2) = n;
      const Eigen::Quaterniond q(r);
      const double su = width * du.norm(), sv = width * std::abs(dv.dot(b));
      const double sn = 0.1 * std::min(su, std::max(sv, 1e-9));
      for (int c = 0; c < 3; ++c) means.push_back(static_cast<float>(p[c]));
      for (double s : {su, std::max(sv, 0.25 * su), sn}) scales.push_back(static_cast<float>(s));
      for (double v : {q.w(), q.x(), q.y(), q.z()}) quats.push_back(static_cast<float>(v));
      opacities.push_back(opacity);
      for (int c = 0; c < 3; ++c) colours.push_back(std::clamp(colour.at(y, x, c), 0.f, 1.f));
    }
  const int64_t n = static_cast<int64_t>(opacities.size());
  auto tensor = [n](const std::vector<float>& v, int64_t width) {
    return torch::from_blob(const_cast<float*>(v.data()), {n, width}, torch::kFloat32).clone();
  };
  GaussianSet g;
  g.means = tensor(means, 3);
  g.scales = tensor(scales, 3);
  g.quats = tensor(quats, 4);
  g.opacities = tensor(opacities, 1).squeeze(1);
  g.colors = tensor(colours, 3);
  return g;
}

GaussianSet backing_gaussians(const Camera& camera, const torch::Tensor& depth, const torch::Tensor& take,
                              const Image& colour, float opacity) {
  const int hw = camera.K.width / 2, hh = camera.K.height / 2;
  if (hw == 0 || hh == 0) return {};
  if (colour.width != camera.K.width || colour.height != camera.K.height || colour.channels < 3)
    fail("backing_gaussians: the colour picture is {}x{}, the camera {}x{}", colour.width, colour.height,
         camera.K.width, camera.K.height);
  auto blocks = [&](const torch::Tensor& t) {  // (H, W, ...) -> (H/2, W/2, 4, ...): each 2 x 2 block's pixels
    torch::Tensor b = t.to(torch::kCPU).narrow(0, 0, 2 * hh).narrow(1, 0, 2 * hw);
    std::vector<int64_t> shape = {hh, 2, hw, 2};
    for (int64_t d = 2; d < t.dim(); ++d) shape.push_back(t.size(d));
    b = b.reshape(shape).transpose(1, 2);
    std::vector<int64_t> out = {hh, hw, 4};
    for (int64_t d = 2; d < t.dim(); ++d) out.push_back(t.size(d));
    return b.reshape(out);
  };
  // Each block's farthest pixel, its depth and its colour together: one point of the surface, not
  // a mix of both sides of a seam (the rooms measured alike either way: 28.26 and 28.24 dB).
  const torch::Tensor d = blocks(depth.to(torch::kFloat32));
  const torch::Tensor far = d.argmax(2, true);  // (hh, hw, 1)
  const torch::Tensor picture =
      torch::from_blob(const_cast<float*>(colour.pixels.data()), {colour.height, colour.width, colour.channels},
                       torch::kFloat32)
          .narrow(2, 0, 3);
  const torch::Tensor rgb = blocks(picture).gather(2, far.unsqueeze(3).expand({hh, hw, 1, 3})).squeeze(2).contiguous();
  const torch::Tensor any = blocks(take.to(torch::kBool)).any(2);
  Image half_colour(hw, hh, 3);
  std::copy_n(rgb.data_ptr<float>(), rgb.numel(), half_colour.pixels.begin());
  return surface_gaussians(camera.resized(hw, hh), d.gather(2, far).squeeze(2) * 1.01f, any, half_colour, opacity);
}

}  // namespace ii
