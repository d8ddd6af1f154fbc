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
  const torch::Tensor reference_values = reference_grey.to(torch::kCPU, torch::kFloat32).contiguous();
  const torch::Tensor source_values = source_grey.to(torch::kCPU, torch::kFloat32).contiguous();
  const torch::Tensor depth_values = depths.to(torch::kCPU, torch::kFloat32).contiguous();
  const float* reference = reference_values.data_ptr<float>();
  const float* source = source_values.data_ptr<float>();
  const float* depth = depth_values.data_ptr<float>();

  // Each reference pixel's ray turned into the source camera's frame (z = 1 before turning).
  const Eigen::Matrix4d to_source = source_camera.w2c_opencv() * reference_camera.w2c_opencv().inverse();
  const Eigen::Matrix3f R = to_source.topLeftCorner<3, 3>().cast<float>();
  const Eigen::Vector3f t = to_source.topRightCorner<3, 1>().cast<float>();
  std::vector<float> ray(static_cast<size_t>(3 * n));
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x) {
      const Eigen::Vector3f direction((x + 0.5 - reference_camera.K.cx) / reference_camera.K.fx,
                                      (y + 0.5 - reference_camera.K.cy) / reference_camera.K.fy, 1.f);
      const Eigen::Vector3f turned = R * direction;
      for (int a = 0; a < 3; ++a) ray[static_cast<size_t>(a * n + y * w + x)] = turned[a];
    }

  // The reference's window means and standard deviations, once.
  const std::vector<float> inverse_count = inverse_counts(h, w, half);
  std::vector<float> reference_stats(static_cast<size_t>(2 * n)), across(static_cast<size_t>(2 * n)),
      sums(static_cast<size_t>(2 * n));
  for (int64_t p = 0; p < n; ++p) {
    reference_stats[static_cast<size_t>(p)] = reference[p];
    reference_stats[static_cast<size_t>(n + p)] = reference[p] * reference[p];
  }
  sweep_detail::window_sums(reference_stats.data(), across.data(), sums.data(), 2, h, w, half);
  std::vector<float> reference_mean(static_cast<size_t>(n)), reference_deviation(static_cast<size_t>(n));
  for (size_t p = 0; p < static_cast<size_t>(n); ++p) {
    const float mean = sums[p] * inverse_count[p];
    reference_mean[p] = mean;
    reference_deviation[p] = std::sqrt(std::max(0.f, sums[static_cast<size_t>(n) + p] * inverse_count[p] - mean * mean));
  }

  // The source with a border of one zero pixel: the kernel's samples need no bounds checks.
  std::vector<float> bordered(static_cast<size_t>((source_h + 2) * (source_w + 2)), 0.f);
  for (int64_t y = 0; y < source_h; ++y)
    std::copy(source + y * source_w, source + (y + 1) * source_w,
              &bordered[static_cast<size_t>((y + 1) * (source_w + 2) + 1)]);

  torch::Tensor out = torch::empty({planes, h, w}, torch::kFloat32);
  sweep_detail::SweepIo io{h, w, source_h, source_w, bordered.data(), reference, reference_mean.data(),
                           reference_deviation.data(), inverse_count.data(), ray.data(), {t[0], t[1], t[2]},
                           static_cast<float>(source_camera.K.fx), static_cast<float>(source_camera.K.fy),
                           static_cast<float>(source_camera.K.cx - 0.5), static_cast<float>(source_camera.K.cy - 0.5),
                           depth, half, out.data_ptr<float>()};
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
