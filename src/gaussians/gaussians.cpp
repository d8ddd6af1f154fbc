#include "gaussians/gaussians.h"

#include <cmath>

#include "common/error.h"

namespace ii {

namespace {

torch::Tensor from_vector(const std::vector<float>& v, std::vector<int64_t> shape) {
  return torch::from_blob(const_cast<float*>(v.data()), shape, torch::kFloat32).clone();
}

std::vector<float> to_vector(const torch::Tensor& t) {
  const torch::Tensor c = t.to(torch::kCPU, torch::kFloat32).contiguous();
  return std::vector<float>(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
}

}  // namespace

GaussianSet GaussianSet::to(const torch::Device& device) const {
  GaussianSet g = *this;
  for (torch::Tensor* t : {&g.means, &g.quats, &g.scales, &g.opacities, &g.colors})
    if (t->defined()) *t = t->to(device);
  return g;
}

BoundingSphere visible_bounds(const GaussianSet& g) {
  if (g.size() == 0) fail("visible_bounds: no splats");
  const torch::Tensor keep = g.opacities.reshape({-1}) > 0.1;
  const torch::Tensor means = (keep.any().item<bool>() ? g.means.index({keep}) : g.means).to(torch::kFloat64);
  const torch::Tensor levels = torch::tensor({0.02, 0.98}, torch::TensorOptions(torch::kFloat64).device(means.device()));
  const torch::Tensor box = means.quantile(levels, 0);  // (2, 3)
  const torch::Tensor mid = box.mean(0);
  BoundingSphere s;
  s.centre = Eigen::Vector3d(mid[0].item<double>(), mid[1].item<double>(), mid[2].item<double>());
  s.radius = 0.5 * (box[1] - box[0]).norm().item<double>();
  return s;
}

torch::Tensor rgb_from_sh_dc(const torch::Tensor& dc) { return 0.5 + kSh0 * dc; }
torch::Tensor sh_dc_from_rgb(const torch::Tensor& rgb) { return (rgb - 0.5) / kSh0; }

GaussianSet joined(const GaussianSet& kept, const GaussianSet& added) {
  GaussianSet out;
  out.means = torch::cat({kept.means, added.means});
  out.scales = torch::cat({kept.scales, added.scales});
  out.quats = torch::cat({kept.quats, added.quats});
  out.opacities = torch::cat({kept.opacities.reshape({-1}), added.opacities.reshape({-1})});
  out.sh_degree = kept.sh_degree;
  if (kept.sh_degree < 0) {
    out.colors = torch::cat({kept.colors, added.colors});
  } else {
    torch::Tensor sh = torch::zeros({added.size(), kept.colors.size(1), 3}, kept.colors.options());
    sh.select(1, 0).copy_(sh_dc_from_rgb(added.colors));
    out.colors = torch::cat({kept.colors, sh});
  }
  return out;
}

GaussianMaps cloned(const GaussianMaps& maps, unsigned which) {
  auto copy = [which](const torch::Tensor& t, MapAttribute a) {
    return t.defined() && (which & a) ? t.clone(torch::MemoryFormat::Contiguous) : t;
  };
  return {copy(maps.depth, kDepthMap), copy(maps.rgb, kRgbMap),           copy(maps.opacity, kOpacityMap),
          copy(maps.scale, kScaleMap), copy(maps.rotation, kRotationMap), copy(maps.xyz, kXyzMap)};
}

GaussianMaps narrowed(const GaussianMaps& maps, int64_t dim, int64_t index) {
  auto part = [&](const torch::Tensor& t) { return t.defined() ? t.narrow(dim, index, 1) : t; };
  return {part(maps.depth), part(maps.rgb), part(maps.opacity), part(maps.scale), part(maps.rotation), part(maps.xyz)};
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

SplatCloud splats_from_gaussians(const GaussianSet& g) {
  const torch::Tensor opacity = g.opacities.reshape({-1}).to(torch::kFloat32).clamp(1e-6, 1.0 - 1e-6);
  SplatCloud c;
  c.means = to_vector(g.means);
  c.normals.assign(c.means.size(), 0.f);
  if (g.sh_degree < 0) {
    c.sh_dc = to_vector(sh_dc_from_rgb(g.colors.to(torch::kFloat32)));
  } else {
    const int64_t used = (g.sh_degree + 1) * (g.sh_degree + 1);
    if (g.colors.dim() != 3 || g.colors.size(1) < used || g.colors.size(2) != 3)
      fail("splats_from_gaussians: SH degree {} needs colours of shape (N, {}, 3) or more coefficients",
           g.sh_degree, used);
    const torch::Tensor sh = g.colors.to(torch::kFloat32).narrow(1, 0, used);
    c.sh_dc = to_vector(sh.select(1, 0));
    // The file's order: per splat, every coefficient of R, then of G, then of B.
    c.sh_rest = to_vector(sh.narrow(1, 1, used - 1).transpose(1, 2));
    c.sh_rest_per_channel = static_cast<int>(used - 1);
  }
  c.opacity_logit = to_vector(torch::log(opacity / (1.0 - opacity)));
  c.log_scales = to_vector(g.scales.to(torch::kFloat32).clamp_min(1e-12).log());  // flat splats: zero scales
  c.rotations = to_vector(g.quats);
  return c;
}

GaussianSet select_rows(const GaussianSet& g, const torch::Tensor& take) {
  // A mask's rows found once, not once a tensor (on a GPU each finding waits for the device);
  // LibTorch's indexing kernel, not index_select (3x slower for rows this narrow on a CPU).
  const torch::Tensor rows = take.scalar_type() == torch::kBool ? take.nonzero().squeeze(1) : take;
  GaussianSet out;
  out.means = g.means.index({rows});
  out.quats = g.quats.index({rows});
  out.scales = g.scales.index({rows});
  out.opacities = g.opacities.index({rows});
  out.colors = g.colors.index({rows});
  out.sh_degree = g.sh_degree;
  return out;
}

}  // namespace ii
