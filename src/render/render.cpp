// render(): input checks, the autograd wrapper and the CPU/CUDA dispatch.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <vector>

#include "common/error.h"
#include "render/cpu/cpu_rasterizer.h"
#include "render/rasterizer.h"
#include "render/render_internal.h"

namespace ii {

using render_detail::RasterGrads;
using render_detail::RasterInputs;
using render_detail::RasterOutputs;
using render_detail::RasterState;

namespace render_detail {

splat::CameraParams camera_params(const RenderCamera& rc, const RenderOptions& options) {
  const Intrinsics& K = rc.camera.K;
  auto finite = [](double v) { return std::isfinite(v); };
  if (K.width < 1 || K.height < 1)
    fail("render: image size must be at least 1x1, not {}x{}", K.width, K.height);
  if (int64_t(K.width) * K.height > (int64_t(1) << 30))
    fail("render: image size {}x{} is too large", K.width, K.height);
  if (!(K.fx > 0) || !(K.fy > 0) || !finite(K.fx) || !finite(K.fy) || !finite(K.cx) || !finite(K.cy))
    fail("render: focal lengths must be positive and finite and the principal point finite (fx {}, fy {}, cx {}, cy {})",
         K.fx, K.fy, K.cx, K.cy);
  if (!(rc.near_plane > 0) || !(rc.far_plane > rc.near_plane))
    fail("render: need 0 < near < far, not near {} far {}", rc.near_plane, rc.far_plane);
  if (!(options.eps2d >= 0) || !finite(options.eps2d)) fail("render: eps2d must be >= 0, not {}", options.eps2d);
  const Eigen::Matrix4d w2c = rc.camera.w2c_opencv();
  if (!w2c.allFinite()) fail("render: the camera pose is not finite");

  splat::CameraParams p;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) p.R[i * 3 + j] = w2c(i, j);
    p.t[i] = w2c(i, 3);
    p.campos[i] = rc.camera.c2w(i, 3);
    p.background[i] = options.background[i];
  }
  p.fx = K.fx;
  p.fy = K.fy;
  p.cx = K.cx;
  p.cy = K.cy;
  p.width = K.width;
  p.height = K.height;
  p.near_plane = rc.near_plane;
  p.far_plane = rc.far_plane;
  p.eps2d = options.eps2d;
  return p;
}

namespace {

// CameraParams and the colour layout travel through the autograd context as one double
// tensor (saved_data holds IValues, not arbitrary structs).
constexpr int kPackedSize = 31;

torch::Tensor pack(const splat::CameraParams& p, int sh_degree, int num_coeffs) {
  std::vector<double> v;
  v.insert(v.end(), p.R, p.R + 9);
  v.insert(v.end(), p.t, p.t + 3);
  v.insert(v.end(), p.campos, p.campos + 3);
  v.insert(v.end(), {p.fx, p.fy, p.cx, p.cy, double(p.width), double(p.height), p.near_plane, p.far_plane, p.eps2d});
  v.insert(v.end(), p.background, p.background + 3);
  v.insert(v.end(), {double(sh_degree), double(num_coeffs)});
  return torch::tensor(v, torch::kFloat64);
}

splat::CameraParams unpack(const torch::Tensor& t, int& sh_degree, int& num_coeffs) {
  const double* v = t.data_ptr<double>();
  splat::CameraParams p;
  std::copy(v, v + 9, p.R);
  std::copy(v + 9, v + 12, p.t);
  std::copy(v + 12, v + 15, p.campos);
  p.fx = v[15];
  p.fy = v[16];
  p.cx = v[17];
  p.cy = v[18];
  p.width = static_cast<int>(v[19]);
  p.height = static_cast<int>(v[20]);
  p.near_plane = v[21];
  p.far_plane = v[22];
  p.eps2d = v[23];
  std::copy(v + 24, v + 27, p.background);
  sh_degree = static_cast<int>(v[27]);
  num_coeffs = static_cast<int>(v[28]);
  return p;
}

RasterOutputs run_forward(const splat::CameraParams& cam, const RasterInputs& in, RasterState* state) {
  if (in.means.is_cuda()) return cuda_forward(cam, in, state);
  return cpu_forward(cam, in, state);
}

const char* const kStateKeys[] = {"splats", "boxes", "tile_offsets", "tile_gaussians", "last", "final_T"};

class RenderFunction : public torch::autograd::Function<RenderFunction> {
 public:
  static torch::autograd::variable_list forward(torch::autograd::AutogradContext* ctx, const torch::Tensor& means,
                                                const torch::Tensor& quats, const torch::Tensor& scales,
                                                const torch::Tensor& opacities, const torch::Tensor& colors,
                                                const torch::Tensor& packed) {
    RasterInputs in{means, quats, scales, opacities, colors, 0, 0};
    const splat::CameraParams cam = unpack(packed, in.sh_degree, in.num_coeffs);
    RasterState st;
    RasterOutputs out = run_forward(cam, in, &st);
    ctx->save_for_backward({means, quats, scales, opacities, colors});
    ctx->saved_data["packed"] = packed;
    // Copies, not the outputs themselves: an output stored on its own grad_fn's context
    // would be a reference cycle.
    ctx->saved_data["alpha"] = out.alpha.clone();
    ctx->saved_data["depth"] = out.depth.clone();
    const torch::Tensor* parts[] = {&st.splats, &st.boxes, &st.tile_offsets, &st.tile_gaussians, &st.last,
                                    &st.final_T};
    for (int i = 0; i < 6; ++i) ctx->saved_data[kStateKeys[i]] = *parts[i];
    return {out.rgb, out.alpha, out.depth};
  }

  static torch::autograd::variable_list backward(torch::autograd::AutogradContext* ctx,
                                                 torch::autograd::variable_list grads) {
    const auto saved = ctx->get_saved_variables();
    RasterInputs in{saved[0], saved[1], saved[2], saved[3], saved[4], 0, 0};
    const splat::CameraParams cam = unpack(ctx->saved_data["packed"].toTensor(), in.sh_degree, in.num_coeffs);
    RasterState st;
    torch::Tensor* parts[] = {&st.splats, &st.boxes, &st.tile_offsets, &st.tile_gaussians, &st.last, &st.final_T};
    for (int i = 0; i < 6; ++i) *parts[i] = ctx->saved_data[kStateKeys[i]].toTensor();
    RasterOutputs out;
    out.alpha = ctx->saved_data["alpha"].toTensor();
    out.depth = ctx->saved_data["depth"].toTensor();
    auto grad = [&](size_t i) {
      return i < grads.size() && grads[i].defined() ? grads[i].contiguous() : torch::Tensor();
    };
    const RasterGrads g = in.means.is_cuda()
                              ? cuda_backward(cam, in, st, out, grad(0), grad(1), grad(2))
                              : cpu_backward(cam, in, st, out, grad(0), grad(1), grad(2));
    return {g.means, g.quats, g.scales, g.opacities, g.colors, torch::Tensor()};
  }
};

std::string shape_string(const torch::Tensor& t) {
  std::vector<int64_t> s(t.sizes().begin(), t.sizes().end());
  return fmt::format("({})", fmt::join(s, ", "));
}

void check_shape(const torch::Tensor& t, const char* name, std::initializer_list<int64_t> shape) {
  if (!t.defined()) fail("render: gaussians.{} is missing", name);
  bool ok = t.dim() == static_cast<int64_t>(shape.size());
  int64_t i = 0;
  for (int64_t s : shape) {
    ok = ok && (s < 0 || t.size(i) == s);
    ++i;
  }
  if (!ok) {
    std::vector<std::string> want;
    for (int64_t s : shape) want.push_back(s < 0 ? "*" : std::to_string(s));
    fail("render: gaussians.{} has shape {}, expected ({})", name, shape_string(t),
         fmt::join(want, ", "));
  }
}

}  // namespace

// Checks shapes, dtypes and devices; returns contiguous tensors of the dtype of means.
// The conversions are differentiable, so gradients reach the caller's tensors.
RasterInputs prepare_inputs(const GaussianSet& g) {
  if (!g.means.defined()) fail("render: gaussians.means is missing");
  check_shape(g.means, "means", {-1, 3});
  const int64_t n = g.means.size(0);
  check_shape(g.quats, "quats", {n, 4});
  check_shape(g.scales, "scales", {n, 3});
  if (!g.opacities.defined()) fail("render: gaussians.opacities is missing");
  if (!(g.opacities.dim() == 1 && g.opacities.size(0) == n) &&
      !(g.opacities.dim() == 2 && g.opacities.size(0) == n && g.opacities.size(1) == 1))
    fail("render: gaussians.opacities has shape {}, expected ({}) or ({}, 1)", shape_string(g.opacities),
         n, n);
  if (g.sh_degree < -1 || g.sh_degree > 3) fail("render: sh_degree must be -1 (RGB) or 0..3, not {}", g.sh_degree);
  int num_coeffs = 0;
  if (g.sh_degree < 0) {
    check_shape(g.colors, "colors", {n, 3});
  } else {
    check_shape(g.colors, "colors", {n, -1, 3});
    num_coeffs = static_cast<int>(g.colors.size(1));
    if (num_coeffs < splat::sh_coeff_count(g.sh_degree))
      fail("render: sh_degree {} needs at least {} SH coefficients per channel, colors has {}", g.sh_degree,
           splat::sh_coeff_count(g.sh_degree), num_coeffs);
  }
  const auto dtype = g.means.scalar_type();
  if (dtype != torch::kFloat32 && dtype != torch::kFloat64)
    fail("render: gaussians.means must be float32 or float64, not {}", c10::toString(dtype));
  const auto device = g.means.device();
  for (const auto* t : {&g.quats, &g.scales, &g.opacities, &g.colors}) {
    if (t->device() != device) fail("render: all Gaussian tensors must be on {} like means", device.str());
    if (!at::isFloatingType(t->scalar_type())) fail("render: Gaussian tensors must be floating point");
  }
  if (device.is_cuda() && !render_has_cuda())
    fail("render: CUDA tensors given, but this build has no CUDA rasterizer (or no GPU is available)");
  if (!device.is_cuda() && !device.is_cpu()) fail("render: unsupported device {}", device.str());
  if (n > (int64_t(1) << 31) - 1) fail("render: too many Gaussians ({})", n);

  auto prep = [&](const torch::Tensor& t) { return t.to(dtype).contiguous(); };
  RasterInputs in;
  in.means = prep(g.means);
  in.quats = prep(g.quats);
  in.scales = prep(g.scales);
  in.opacities = prep(g.opacities.reshape({n}));
  in.colors = prep(g.colors);
  in.sh_degree = g.sh_degree;
  in.num_coeffs = num_coeffs;
  return in;
}

}  // namespace render_detail

bool render_has_cuda() {
#ifdef INSTAINPAINT_HAS_CUDA_KERNELS
  return torch::cuda::is_available();
#else
  return false;
#endif
}

torch::Device render_device(const torch::Device& device) {
  return !device.is_cuda() || render_has_cuda() ? device : torch::Device(torch::kCPU);
}

RenderOutput render(const GaussianSet& gaussians, const RenderCamera& camera, const RenderOptions& options) {
  const splat::CameraParams cam = render_detail::camera_params(camera, options);
  RasterInputs in = render_detail::prepare_inputs(gaussians);
  const bool needs_grad = torch::GradMode::is_enabled() &&
                          (in.means.requires_grad() || in.quats.requires_grad() || in.scales.requires_grad() ||
                           in.opacities.requires_grad() || in.colors.requires_grad());
  RenderOutput out;
  if (!needs_grad) {
    const RasterOutputs r = render_detail::run_forward(cam, in, nullptr);
    out.rgb = r.rgb;
    out.alpha = r.alpha;
    out.depth = r.depth;
    return out;
  }
  const auto v = render_detail::RenderFunction::apply(in.means, in.quats, in.scales, in.opacities, in.colors,
                                       render_detail::pack(cam, in.sh_degree, in.num_coeffs));
  out.rgb = v[0];
  out.alpha = v[1];
  out.depth = v[2];
  return out;
}

}  // namespace ii
