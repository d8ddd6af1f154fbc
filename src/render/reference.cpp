// render_reference(): the rasterizer's semantics written as directly as possible with
// LibTorch operations, independent of the tiled kernels (no splat_math.h), so tests can
// compare the two and LibTorch's autograd checks the analytic backward.
#include <cmath>

#include "render/render_internal.h"

namespace ii {

namespace {

using torch::indexing::Slice;

// Rotation matrices (N,3,3) of unit quaternions (N,4) in (w,x,y,z) order.
torch::Tensor rotations(const torch::Tensor& q) {
  const auto w = q.select(1, 0), x = q.select(1, 1), y = q.select(1, 2), z = q.select(1, 3);
  const auto r0 = torch::stack({1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)}, 1);
  const auto r1 = torch::stack({2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)}, 1);
  const auto r2 = torch::stack({2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}, 1);
  return torch::stack({r0, r1, r2}, 1);
}

// Real SH up to degree 3 at unit directions d (N,3), times coefficients (N,K,3) -> (N,3).
torch::Tensor eval_sh(int degree, const torch::Tensor& coeffs, const torch::Tensor& d) {
  const auto x = d.select(1, 0), y = d.select(1, 1), z = d.select(1, 2);
  std::vector<torch::Tensor> b{torch::full_like(x, 0.28209479177387814)};
  if (degree >= 1) {
    const double c1 = 0.4886025119029199;
    b.insert(b.end(), {-c1 * y, c1 * z, -c1 * x});
  }
  if (degree >= 2) {
    const auto xx = x * x, yy = y * y, zz = z * z;
    b.insert(b.end(), {1.0925484305920792 * x * y, -1.0925484305920792 * y * z,
                       0.31539156525252005 * (2 * zz - xx - yy), -1.0925484305920792 * x * z,
                       0.5462742152960396 * (xx - yy)});
    if (degree >= 3)
      b.insert(b.end(), {-0.5900435899266435 * y * (3 * xx - yy), 2.890611442640554 * x * y * z,
                         -0.4570457994644658 * y * (4 * zz - xx - yy),
                         0.3731763325901154 * z * (2 * zz - 3 * xx - 3 * yy),
                         -0.4570457994644658 * x * (4 * zz - xx - yy), 1.445305721320277 * z * (xx - yy),
                         -0.5900435899266435 * x * (xx - 3 * yy)});
  }
  const auto basis = torch::stack(b, 1);  // (N, k)
  const int64_t k = basis.size(1);
  return (basis.unsqueeze(2) * coeffs.index({Slice(), Slice(0, k), Slice()})).sum(1);
}

}  // namespace

RenderOutput render_reference(const GaussianSet& gaussians, const RenderCamera& camera,
                              const RenderOptions& options) {
  const splat::CameraParams cam = render_detail::camera_params(camera, options);
  const render_detail::RasterInputs in = render_detail::prepare_inputs(gaussians);
  const auto dtype = in.means.scalar_type();
  const auto topt = torch::TensorOptions().dtype(dtype);
  const int W = cam.width, H = cam.height;

  // Skip Gaussians with any non-finite parameter.
  auto row_finite = [](const torch::Tensor& t) { return torch::isfinite(t).reshape({t.size(0), -1}).all(1); };
  const int64_t n0 = in.means.size(0);
  torch::Tensor keep = torch::ones({n0}, torch::kBool);
  for (const auto* t : {&in.means, &in.quats, &in.scales, &in.opacities, &in.colors}) keep &= row_finite(*t);
  const auto idx = keep.nonzero().reshape({-1});
  const auto means = in.means.index_select(0, idx), quats = in.quats.index_select(0, idx);
  const auto scales = in.scales.index_select(0, idx), opac = in.opacities.index_select(0, idx);
  const auto colors_in = in.colors.index_select(0, idx);

  const torch::Tensor Rw = torch::tensor(std::vector<double>(cam.R, cam.R + 9), torch::kFloat64).reshape({3, 3}).to(dtype);
  const torch::Tensor tw = torch::tensor(std::vector<double>(cam.t, cam.t + 3), torch::kFloat64).to(dtype);

  // Camera-space means and covariances.
  const auto p = torch::matmul(means, Rw.t()) + tw;
  const auto x = p.select(1, 0), y = p.select(1, 1), z = p.select(1, 2);
  const auto qn = quats / quats.norm(2, 1, true).clamp_min(1e-12);
  const auto M = rotations(qn) * scales.unsqueeze(1);  // R diag(s)
  const auto cov = torch::matmul(M, M.transpose(1, 2));
  const auto cov_c = torch::matmul(torch::matmul(Rw, cov), Rw.t());

  // Perspective Jacobian with x/z, y/z clamped to 1.3x the image extent.
  const double tan_x = 0.5 * W / cam.fx, tan_y = 0.5 * H / cam.fy;
  const auto u = (x / z).clamp(-(cam.cx / cam.fx + 0.3 * tan_x), (W - cam.cx) / cam.fx + 0.3 * tan_x);
  const auto v = (y / z).clamp(-(cam.cy / cam.fy + 0.3 * tan_y), (H - cam.cy) / cam.fy + 0.3 * tan_y);
  const auto zero = torch::zeros_like(z);
  const auto J = torch::stack({torch::stack({cam.fx / z, zero, -cam.fx * u / z}, 1),
                               torch::stack({zero, cam.fy / z, -cam.fy * v / z}, 1)},
                              1);  // (N,2,3)
  const auto cov2d = torch::matmul(torch::matmul(J, cov_c), J.transpose(1, 2)) +
                     cam.eps2d * torch::eye(2, topt).unsqueeze(0);
  const auto a = cov2d.select(1, 0).select(1, 0), b = cov2d.select(1, 0).select(1, 1),
             c = cov2d.select(1, 1).select(1, 1);
  const auto det = a * c - b * b;
  const auto conA = c / det, conB = -b / det, conC = a / det;
  const auto mx = cam.fx * x / z + cam.cx, my = cam.fy * y / z + cam.cy;

  torch::Tensor rgb;
  if (in.sh_degree < 0) {
    rgb = colors_in;
  } else {
    torch::Tensor campos = torch::tensor({cam.campos[0], cam.campos[1], cam.campos[2]}, torch::kFloat64).to(dtype);
    const auto dir = means - campos;
    const auto dn = dir / dir.norm(2, 1, true);
    rgb = (eval_sh(in.sh_degree, colors_in, dn) + 0.5).clamp_min(0.0);
  }

  // Culling and the 3-sigma tile footprint (not differentiable).
  const int tiles_x = cam.tiles_x(), tiles_y = cam.tiles_y();
  const auto ad = a.detach().to(torch::kFloat64), cd = c.detach().to(torch::kFloat64);
  const auto half = 0.5 * (ad + cd);
  const auto v1 = half + (half * half - det.detach().to(torch::kFloat64)).clamp_min(0.01).sqrt();
  const auto radius = (3.0 * v1.sqrt()).ceil();
  const auto mxd = mx.detach().to(torch::kFloat64), myd = my.detach().to(torch::kFloat64);
  const auto zd = z.detach();
  auto visible = (zd >= cam.near_plane) & (zd <= cam.far_plane) & (det.detach() > 0) & torch::isfinite(det.detach()) &
                 (mxd + radius > 0) & (mxd - radius < W) & (myd + radius > 0) & (myd - radius < H);
  const auto tx0 = (mxd / 16 - radius / 16).floor().clamp(0, tiles_x);
  const auto tx1 = (mxd / 16 + radius / 16).ceil().clamp(0, tiles_x);
  const auto ty0 = (myd / 16 - radius / 16).floor().clamp(0, tiles_y);
  const auto ty1 = (myd / 16 + radius / 16).ceil().clamp(0, tiles_y);
  visible &= (tx1 > tx0) & (ty1 > ty0);

  // Depth order (camera z as float32, ties by index), visible only.
  const auto vis_idx = visible.nonzero().reshape({-1});
  const auto key = zd.index_select(0, vis_idx).to(torch::kFloat32);
  const auto order = vis_idx.index_select(0, std::get<1>(key.sort(/*stable=*/true, 0, false)));

  // All pixels at once.
  const auto pix_x = (torch::arange(W, topt) + 0.5).repeat({H});
  const auto pix_y = (torch::arange(H, topt) + 0.5).repeat_interleave(W);
  const auto tile_x = (torch::arange(W, torch::kFloat64) / 16).floor().repeat({H});
  const auto tile_y = (torch::arange(H, torch::kFloat64) / 16).floor().repeat_interleave(W);
  torch::Tensor T = torch::ones({H * W}, topt);
  torch::Tensor color = torch::zeros({H * W, 3}, topt);
  torch::Tensor dsum = torch::zeros({H * W}, topt);
  torch::Tensor done = torch::zeros({H * W}, torch::kBool);

  const auto ord = order.accessor<int64_t, 1>();
  const auto tx0a = tx0.accessor<double, 1>(), tx1a = tx1.accessor<double, 1>();
  const auto ty0a = ty0.accessor<double, 1>(), ty1a = ty1.accessor<double, 1>();
  for (int64_t k = 0; k < ord.size(0); ++k) {
    const int64_t g = ord[k];
    const auto in_tiles = (tile_x >= tx0a[g]) & (tile_x < tx1a[g]) & (tile_y >= ty0a[g]) & (tile_y < ty1a[g]);
    const auto dx = mx[g] - pix_x, dy = my[g] - pix_y;
    const auto sigma = 0.5 * (conA[g] * dx * dx + conC[g] * dy * dy) + conB[g] * dx * dy;
    const auto alpha = (opac[g] * torch::exp(-sigma)).clamp_max(splat::kAlphaMax);
    const auto ok = in_tiles & ~done & (sigma >= 0) & (alpha >= splat::kAlphaMin);
    const auto stop = ok & (T * (1 - alpha) <= splat::kTransmittanceMin);
    done = done | stop;
    const auto used = torch::where(ok & ~stop, alpha, torch::zeros_like(alpha));
    const auto w = used * T;
    color = color + w.unsqueeze(1) * rgb[g];
    dsum = dsum + w * z[g];
    T = T * (1 - used);
  }

  torch::Tensor bg = torch::tensor({cam.background[0], cam.background[1], cam.background[2]}, torch::kFloat64).to(dtype);
  RenderOutput out;
  out.rgb = (color + T.unsqueeze(1) * bg).reshape({H, W, 3});
  const auto acc = 1 - T;
  out.alpha = acc.reshape({H, W, 1});
  out.depth = (dsum / acc.clamp_min(1e-10)).reshape({H, W, 1});
  return out;
}

}  // namespace ii
