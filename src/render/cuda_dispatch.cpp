// Glue between render() and the CUDA kernels (src/render/cuda), which take raw device
// pointers so that they build without a CUDA LibTorch. Without the kernels every entry
// point says so.
#include "common/error.h"
#include "render/render_internal.h"

#ifdef INSTAINPAINT_HAS_CUDA_KERNELS
#include "render/cuda/rasterizer_cuda.h"
#endif

namespace ii::render_detail {

#ifdef INSTAINPAINT_HAS_CUDA_KERNELS

namespace {

// Scratch memory from LibTorch's caching allocator: the tensors stay alive in `keep`.
struct TorchScratch {
  torch::Device device;
  std::vector<torch::Tensor> keep;
  void* operator()(size_t bytes) {
    keep.push_back(torch::empty({static_cast<int64_t>(bytes ? bytes : 1)},
                                torch::TensorOptions().dtype(torch::kUInt8).device(device)));
    return keep.back().data_ptr();
  }
};

cuda::SplatInputs device_inputs(const RasterInputs& in) {
  cuda::SplatInputs d;
  d.count = in.means.size(0);
  d.sh_degree = in.sh_degree;
  d.num_coeffs = in.num_coeffs;
  d.is_double = in.means.scalar_type() == torch::kFloat64;
  d.device = in.means.device().has_index() ? in.means.device().index() : 0;
  d.means = in.means.data_ptr();
  d.quats = in.quats.data_ptr();
  d.scales = in.scales.data_ptr();
  d.opacities = in.opacities.data_ptr();
  d.colors = in.colors.data_ptr();
  return d;
}

}  // namespace

RasterOutputs cuda_forward(const splat::CameraParams& cam, const RasterInputs& in, RasterState* state) {
  const auto opts = in.means.options();
  const auto iopts = opts.dtype(torch::kInt32);
  const int64_t n = in.means.size(0);
  RasterState local;
  RasterState& st = state ? *state : local;
  st.splats = torch::empty({n, splat::kSplatScalars}, opts);
  st.boxes = torch::empty({n, 4}, iopts);
  st.tile_offsets = torch::empty({cam.tiles_x() * cam.tiles_y() + 1}, opts.dtype(torch::kInt64));
  st.last = torch::empty({cam.height, cam.width}, iopts);
  st.final_T = torch::empty({cam.height, cam.width}, opts);
  RasterOutputs out;
  out.rgb = torch::empty({cam.height, cam.width, 3}, opts);
  out.alpha = torch::empty({cam.height, cam.width, 1}, opts);
  out.depth = torch::empty({cam.height, cam.width, 1}, opts);

  TorchScratch scratch{in.means.device(), {}};
  cuda::ForwardBuffers b;
  b.splats = st.splats.data_ptr();
  b.boxes = st.boxes.data_ptr<int32_t>();
  b.tile_offsets = st.tile_offsets.data_ptr<int64_t>();
  b.last = st.last.data_ptr<int32_t>();
  b.final_T = st.final_T.data_ptr();
  b.rgb = out.rgb.data_ptr();
  b.alpha = out.alpha.data_ptr();
  b.depth = out.depth.data_ptr();
  // The tile list's length is known only after counting: allocate it through a callback.
  torch::Tensor list;
  b.alloc_tile_gaussians = [&](int64_t m) {
    list = torch::empty({std::max<int64_t>(m, 1)}, iopts);
    return list.data_ptr<int32_t>();
  };
  b.scratch = [&](size_t bytes) { return scratch(bytes); };
  const int64_t m = cuda::forward(cam, device_inputs(in), b);
  st.tile_gaussians = list.defined() ? list.narrow(0, 0, m) : torch::empty({0}, iopts);
  return out;
}

RasterGrads cuda_backward(const splat::CameraParams& cam, const RasterInputs& in, const RasterState& st,
                          const RasterOutputs& out, const torch::Tensor& grad_rgb, const torch::Tensor& grad_alpha,
                          const torch::Tensor& grad_depth) {
  auto prep = [&](const torch::Tensor& g) {
    return g.defined() ? g.to(in.means.scalar_type()).contiguous() : torch::zeros_like(out.alpha);
  };
  const torch::Tensor g_rgb = grad_rgb.defined() ? grad_rgb.to(in.means.scalar_type()).contiguous()
                                                 : torch::zeros_like(out.rgb);
  const torch::Tensor g_alpha = prep(grad_alpha), g_depth = prep(grad_depth);
  RasterGrads gr;
  gr.means = torch::zeros_like(in.means);
  gr.quats = torch::zeros_like(in.quats);
  gr.scales = torch::zeros_like(in.scales);
  gr.opacities = torch::zeros_like(in.opacities);
  gr.colors = torch::zeros_like(in.colors);

  TorchScratch scratch{in.means.device(), {}};
  cuda::BackwardBuffers b;
  b.splats = st.splats.data_ptr();
  b.boxes = st.boxes.data_ptr<int32_t>();
  b.tile_offsets = st.tile_offsets.data_ptr<int64_t>();
  b.tile_gaussians = st.tile_gaussians.data_ptr<int32_t>();
  b.num_entries = st.tile_gaussians.numel();
  b.last = st.last.data_ptr<int32_t>();
  b.final_T = st.final_T.data_ptr();
  b.alpha = out.alpha.data_ptr();
  b.depth = out.depth.data_ptr();
  b.grad_rgb = g_rgb.data_ptr();
  b.grad_alpha = g_alpha.data_ptr();
  b.grad_depth = g_depth.data_ptr();
  b.v_means = gr.means.data_ptr();
  b.v_quats = gr.quats.data_ptr();
  b.v_scales = gr.scales.data_ptr();
  b.v_opacities = gr.opacities.data_ptr();
  b.v_colors = gr.colors.data_ptr();
  b.scratch = [&](size_t bytes) { return scratch(bytes); };
  cuda::backward(cam, device_inputs(in), b);
  return gr;
}

#else

RasterOutputs cuda_forward(const splat::CameraParams&, const RasterInputs&, RasterState*) {
  fail("render: this build has no CUDA rasterizer");
}

RasterGrads cuda_backward(const splat::CameraParams&, const RasterInputs&, const RasterState&, const RasterOutputs&,
                          const torch::Tensor&, const torch::Tensor&, const torch::Tensor&) {
  fail("render: this build has no CUDA rasterizer");
}

#endif

}  // namespace ii::render_detail
