#include "geometry/sweep_correlation.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "common/cpu_features.h"
#include "common/error.h"
#include "common/parallel.h"
#include "geometry/sweep_planes.h"

namespace ii {

namespace {

// 1 / the number of a window's pixels inside the picture, per pixel.
std::vector<float> inverse_counts(int64_t h, int64_t w, int half) {
  std::vector<float> inverse(static_cast<size_t>(h * w));
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) {
      const int64_t rows = std::min(h - 1, y + half) - std::max<int64_t>(0, y - half) + 1;
      const int64_t columns = std::min(w - 1, x + half) - std::max<int64_t>(0, x - half) + 1;
      inverse[static_cast<size_t>(y * w + x)] = 1.f / static_cast<float>(rows * columns);
    }
  return inverse;
}

// Each pixel's ray through `camera` (z = 1) turned by R, as three planes (x, y, z) of h * w.
std::vector<float> turned_rays(const Camera& camera, const Eigen::Matrix3f& R) {
  const int64_t h = camera.K.height, w = camera.K.width, n = h * w;
  std::vector<float> ray(static_cast<size_t>(3 * n));
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) {
      const Eigen::Vector3f direction((x + 0.5 - camera.K.cx) / camera.K.fx, (y + 0.5 - camera.K.cy) / camera.K.fy, 1.f);
      const Eigen::Vector3f turned = R * direction;
      for (int a = 0; a < 3; ++a) ray[static_cast<size_t>(a * n + y * w + x)] = turned[a];
    }
  return ray;
}

// A picture's window means and standard deviations (the part of each window inside the picture).
struct WindowStatistics {
  std::vector<float> mean, deviation;
};

WindowStatistics window_statistics(const float* picture, int64_t h, int64_t w, int half,
                                   const std::vector<float>& inverse_count) {
  const auto n = static_cast<size_t>(h * w);
  std::vector<float> values(2 * n), down(2 * n), sums(2 * n);
  for (size_t p = 0; p < n; ++p) {
    values[p] = picture[p];
    values[n + p] = picture[p] * picture[p];
  }
  sweep_detail::window_sums(values.data(), down.data(), sums.data(), 2, h, w, half);
  WindowStatistics out{std::vector<float>(n), std::vector<float>(n)};
  for (size_t p = 0; p < n; ++p) {
    out.mean[p] = sums[p] * inverse_count[p];
    out.deviation[p] = std::sqrt(std::max(0.f, sums[n + p] * inverse_count[p] - out.mean[p] * out.mean[p]));
  }
  return out;
}

// The picture with a border of one zero pixel around it: the kernel's samples need no bounds checks.
std::vector<float> bordered(const float* picture, int64_t h, int64_t w) {
  std::vector<float> out(static_cast<size_t>((h + 2) * (w + 2)), 0.f);
  for (int64_t y = 0; y < h; ++y)
    std::copy(picture + y * w, picture + (y + 1) * w, &out[static_cast<size_t>((y + 1) * (w + 2) + 1)]);
  return out;
}

}  // namespace

torch::Tensor sweep_correlation(const torch::Tensor& reference_grey, const Camera& reference_camera,
                                const torch::Tensor& source_grey, const Camera& source_camera,
                                const torch::Tensor& depths, int window) {
  const int64_t h = reference_camera.K.height, w = reference_camera.K.width, n = h * w;
  const int64_t source_h = source_camera.K.height, source_w = source_camera.K.width;
  if (reference_grey.numel() != n || source_grey.numel() != source_h * source_w || depths.dim() != 2 ||
      depths.size(1) != n)
    throw Error("the sweep's pictures and depths do not match their cameras' sizes");
  const int64_t planes = depths.size(0);
  const int half = std::max(0, window / 2);
  const torch::Tensor reference = reference_grey.to(torch::kCPU, torch::kFloat32).contiguous();
  const torch::Tensor source = source_grey.to(torch::kCPU, torch::kFloat32).contiguous();
  const torch::Tensor depth = depths.to(torch::kCPU, torch::kFloat32).contiguous();

  const Eigen::Matrix4d to_source = source_camera.w2c_opencv() * reference_camera.w2c_opencv().inverse();
  const Eigen::Vector3f t = to_source.topRightCorner<3, 1>().cast<float>();
  const std::vector<float> ray = turned_rays(reference_camera, to_source.topLeftCorner<3, 3>().cast<float>());
  const std::vector<float> inverse_count = inverse_counts(h, w, half);
  const WindowStatistics statistics = window_statistics(reference.data_ptr<float>(), h, w, half, inverse_count);
  const std::vector<float> source_bordered = bordered(source.data_ptr<float>(), source_h, source_w);

  torch::Tensor out = torch::empty({planes, h, w}, torch::kFloat32);
  const sweep_detail::SweepIo io{h, w, source_h, source_w, source_bordered.data(), reference.data_ptr<float>(),
                                 statistics.mean.data(), statistics.deviation.data(), inverse_count.data(), ray.data(),
                                 {t[0], t[1], t[2]}, static_cast<float>(source_camera.K.fx),
                                 static_cast<float>(source_camera.K.fy), static_cast<float>(source_camera.K.cx - 0.5),
                                 static_cast<float>(source_camera.K.cy - 0.5), depth.data_ptr<float>(), half,
                                 out.data_ptr<float>()};
  const bool avx2 = cpu_features().has(CpuIsa::Avx2);
  parallel_range(planes, 1, at::get_num_threads(), [&](int64_t first, int64_t last) {
    std::vector<float> scratch(static_cast<size_t>(sweep_detail::sweep_scratch_floats(io)));
    if (avx2)
      sweep_detail::sweep_planes_avx2(io, first, last, scratch.data());
    else
      sweep_detail::sweep_planes(io, first, last, scratch.data());
  });
  return out;
}

}  // namespace ii
