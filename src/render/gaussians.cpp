#include "render/gaussians.h"

#include <cmath>

#include "common/error.h"

namespace ii {

namespace {

torch::Tensor from_vector(const std::vector<float>& v, std::vector<int64_t> shape) {
  return torch::from_blob(const_cast<float*>(v.data()), shape, torch::kFloat32).clone();
}

}  // namespace

GaussianSet gaussians_from_splats(const SplatCloud& cloud, int max_sh_degree) {
  const int64_t n = static_cast<int64_t>(cloud.size());
  const int rest = cloud.sh_rest_per_channel;
  auto check = [&](const std::vector<float>& v, int64_t per, const char* name) {
    if (static_cast<int64_t>(v.size()) != n * per)
      fail("splat cloud: {} has {} values, expected {} for {} splats", name, v.size(), n * per, n);
  };
  check(cloud.means, 3, "means");
  check(cloud.sh_dc, 3, "sh_dc");
  check(cloud.sh_rest, 3 * rest, "sh_rest");
  check(cloud.log_scales, 3, "log_scales");
  check(cloud.rotations, 4, "rotations");
  // Degree from the stored coefficient count: (d+1)^2 - 1 rest coefficients per channel.
  int stored_degree = 0;
  while (stored_degree < 3 && (stored_degree + 2) * (stored_degree + 2) - 1 <= rest) ++stored_degree;
  const int degree = std::max(0, std::min(stored_degree, max_sh_degree));
  const int k = (degree + 1) * (degree + 1);

  GaussianSet g;
  g.means = from_vector(cloud.means, {n, 3});
  g.quats = from_vector(cloud.rotations, {n, 4});
  g.scales = from_vector(cloud.log_scales, {n, 3}).exp();
  g.opacities = torch::sigmoid(from_vector(cloud.opacity_logit, {n}));
  torch::Tensor coeffs = torch::empty({n, k, 3}, torch::kFloat32);
  coeffs.select(1, 0).copy_(from_vector(cloud.sh_dc, {n, 3}));
  if (k > 1) {
    // File layout per splat: all R rest coefficients, then G, then B (channel-major).
    const torch::Tensor r = from_vector(cloud.sh_rest, {n, 3, rest});
    coeffs.narrow(1, 1, k - 1).copy_(r.narrow(2, 0, k - 1).transpose(1, 2));
  }
  g.colors = coeffs;
  g.sh_degree = degree;
  return g;
}

GaussianSet gaussians_from_maps(const GaussianMaps& maps) {
  if (!maps.xyz.defined() || maps.xyz.dim() != 5 || maps.xyz.size(0) != 1)
    fail("gaussians_from_maps: expected maps of shape (1, V, C, H, W)");
  // (1, V, C, H, W) -> (V*H*W, C)
  auto flat = [](const torch::Tensor& t) { return t[0].permute({0, 2, 3, 1}).reshape({-1, t.size(2)}); };
  GaussianSet g;
  g.means = flat(maps.xyz);
  g.quats = flat(maps.rotation);
  g.scales = flat(maps.scale);
  g.opacities = flat(maps.opacity).reshape({-1});
  g.colors = flat(maps.rgb);
  g.sh_degree = -1;
  return g;
}

}  // namespace ii
