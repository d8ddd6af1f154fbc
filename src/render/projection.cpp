#include "render/projection.h"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>

#include "common/parallel.h"

namespace ii {

namespace {

// Each Gaussian's centre in pixels and the half-extent of its bounding sphere's projection along
// each image axis (|u(q) - u(p)| <= f R (1 + |x|/z) / (z - R) for every q within R of p), and
// whether it is bounded (in front of the near plane by more than R).
struct SphereFootprint {
  torch::Tensor u, v, du, dv, bounded, in_front;
};

SphereFootprint sphere_footprint(const GaussianSet& g, const Camera& camera) {
  constexpr double kNear = 0.01, kBlurPixels = 2.0;  // the rasterizer's near plane; its 0.3 px^2 blur
  const Intrinsics& K = camera.K;
  const torch::Tensor p = transformed(camera.w2c_opencv(), g.means);
  const torch::Tensor x = p.select(1, 0), y = p.select(1, 1), z = p.select(1, 2);
  const torch::Tensor r = 3 * std::get<0>(g.scales.abs().max(1));
  SphereFootprint f;
  f.in_front = z > kNear;
  f.bounded = z > r + kNear;
  const torch::Tensor zs = z.clamp_min(kNear), gap = (z - r).clamp_min(kNear);
  f.u = x / zs * K.fx + K.cx;
  f.v = y / zs * K.fy + K.cy;
  f.du = K.fx * r * (1 + x.abs() / zs) / gap + kBlurPixels;
  f.dv = K.fy * r * (1 + y.abs() / zs) / gap + kBlurPixels;
  return f;
}

}  // namespace

// One pass over the rows on the CPU (a dozen LibTorch operations over every row cost as much as
// the small render they were to spare).
torch::Tensor reaching_window_cpu(const GaussianSet& g, const Camera& camera, const PixelWindow& w) {
  constexpr double kNear = 0.01, kBlurPixels = 2.0;
  const torch::Tensor means = g.means.to(torch::kFloat32).contiguous(), scales = g.scales.to(torch::kFloat32).contiguous();
  const float* m = means.data_ptr<float>();
  const float* sc = scales.data_ptr<float>();
  const int64_t n = g.size();
  torch::Tensor flags = torch::empty({n}, torch::kBool);
  bool* out = flags.data_ptr<bool>();
  const Eigen::Matrix4d t = camera.w2c_opencv();
  const Intrinsics& K = camera.K;
  parallel_range(n, 1 << 14, thread_plan().compute, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const double px = m[3 * i], py = m[3 * i + 1], pz = m[3 * i + 2];
      const double x = t(0, 0) * px + t(0, 1) * py + t(0, 2) * pz + t(0, 3);
      const double y = t(1, 0) * px + t(1, 1) * py + t(1, 2) * pz + t(1, 3);
      const double z = t(2, 0) * px + t(2, 1) * py + t(2, 2) * pz + t(2, 3);
      const double r = 3 * std::max({std::abs(sc[3 * i]), std::abs(sc[3 * i + 1]), std::abs(sc[3 * i + 2])});
      if (!(z > kNear)) {
        out[i] = false;
        continue;
      }
      if (z <= r + kNear) {
        out[i] = true;  // too near to bound
        continue;
      }
      const double u = x / z * K.fx + K.cx, v = y / z * K.fy + K.cy;
      const double du = K.fx * r * (1 + std::abs(x) / z) / (z - r) + kBlurPixels;
      const double dv = K.fy * r * (1 + std::abs(y) / z) / (z - r) + kBlurPixels;
      out[i] = u + du >= w.x0 && u - du <= w.x1 && v + dv >= w.y0 && v - dv <= w.y1;
    }
  });
  return flags;
}

torch::Tensor reaching_window(const GaussianSet& g, const Camera& camera, const PixelWindow& w) {
  if (g.means.device().is_cpu()) return reaching_window_cpu(g, camera, w);
  const SphereFootprint f = sphere_footprint(g, camera);
  const torch::Tensor overlaps = (f.u + f.du >= w.x0)
                                     .logical_and(f.u - f.du <= w.x1)
                                     .logical_and(f.v + f.dv >= w.y0)
                                     .logical_and(f.v - f.dv <= w.y1);
  return f.in_front.logical_and(f.bounded.logical_not().logical_or(overlaps));
}

std::optional<PixelWindow> covered_window(const GaussianSet& g, const Camera& camera, double margin) {
  if (g.size() == 0) return std::nullopt;
  const SphereFootprint f = sphere_footprint(g, camera);
  if (!f.in_front.any().item<bool>()) return std::nullopt;
  PixelWindow w{0, 0, static_cast<double>(camera.K.width), static_cast<double>(camera.K.height)};
  if (f.in_front.logical_and(f.bounded.logical_not()).any().item<bool>()) return w;  // too near to bound
  const torch::Tensor front = f.in_front;
  w.x0 = std::max(w.x0, (f.u - f.du).index({front}).min().item<double>() - margin);
  w.y0 = std::max(w.y0, (f.v - f.dv).index({front}).min().item<double>() - margin);
  w.x1 = std::min(w.x1, (f.u + f.du).index({front}).max().item<double>() + margin);
  w.y1 = std::min(w.y1, (f.v + f.dv).index({front}).max().item<double>() + margin);
  if (w.x1 <= w.x0 || w.y1 <= w.y0) return std::nullopt;
  return w;
}

torch::Tensor pasted(const torch::Tensor& outside, const torch::Tensor& inside, const PixelWindow& w) {
  const int64_t h = outside.size(0), wd = outside.size(1);
  const int64_t y0 = std::clamp<int64_t>(static_cast<int64_t>(std::floor(w.y0)), 0, h);
  const int64_t y1 = std::clamp<int64_t>(static_cast<int64_t>(std::ceil(w.y1)), y0, h);
  const int64_t x0 = std::clamp<int64_t>(static_cast<int64_t>(std::floor(w.x0)), 0, wd);
  const int64_t x1 = std::clamp<int64_t>(static_cast<int64_t>(std::ceil(w.x1)), x0, wd);
  torch::Tensor out = outside.clone();
  out.slice(0, y0, y1).slice(1, x0, x1).copy_(inside.slice(0, y0, y1).slice(1, x0, x1));
  return out;
}

torch::Tensor unproject(const Camera& camera, const torch::Tensor& v, const torch::Tensor& u, const torch::Tensor& z) {
  const Intrinsics& K = camera.K;
  const torch::Tensor vd = v.to(torch::kFloat64), ud = u.to(torch::kFloat64), zd = z.to(torch::kFloat64);
  const torch::Tensor local = torch::stack({(ud + 0.5 - K.cx) / K.fx * zd, (vd + 0.5 - K.cy) / K.fy * zd, zd}, 1);
  return transformed(camera.w2c_opencv().inverse(), local);
}

torch::Tensor depth_points(const Camera& camera, const torch::Tensor& depth) {
  const int64_t h = depth.size(0), w = depth.size(1);
  const torch::Tensor v = torch::arange(h, torch::kFloat64).unsqueeze(1).expand({h, w}).reshape({-1});
  const torch::Tensor u = torch::arange(w, torch::kFloat64).unsqueeze(0).expand({h, w}).reshape({-1});
  return unproject(camera, v, u, depth.to(torch::kFloat64).reshape({-1})).reshape({h, w, 3});
}

torch::Tensor point_normals(const Camera& camera, const torch::Tensor& p) {
  using torch::indexing::None;
  using torch::indexing::Slice;
  torch::Tensor dx = torch::zeros_like(p), dy = torch::zeros_like(p);
  dx.index_put_({Slice(), Slice(1, -1)}, p.index({Slice(), Slice(2, None)}) - p.index({Slice(), Slice(None, -2)}));
  dy.index_put_({Slice(1, -1)}, p.index({Slice(2, None)}) - p.index({Slice(None, -2)}));
  torch::Tensor n = torch::cross(dx, dy, 2);
  const Eigen::Vector3d c = camera.center();
  const torch::Tensor to_camera = torch::tensor({c.x(), c.y(), c.z()}, torch::kFloat64) - p;
  n = torch::where((n * to_camera).sum(2, true) < 0, -n, n);
  return n / n.norm(2, 2, true).clamp_min(1e-12);
}

torch::Tensor depth_normals(const Camera& camera, const torch::Tensor& depth) {
  return point_normals(camera, depth_points(camera, depth));
}

}  // namespace ii
