#include "model/cuda_graph.h"

#include <fmt/ranges.h>

#include "common/error.h"
#include "common/torch_compat.h"

#if II_HAS_CUDA_TORCH
#include <ATen/cuda/CUDAGraph.h>
#include <c10/cuda/CUDAGuard.h>
#include <c10/cuda/CUDAStream.h>
#endif

namespace ii {

struct GraphedForward::Captured {
  torch::Tensor images, plucker, rays_o, rays_d_un;  // the buffers the graph reads
  GaussianMaps maps;                                 // and writes
#if II_HAS_CUDA_TORCH
  at::cuda::CUDAGraph graph;
#endif
};

bool GraphedForward::available() { return II_HAS_CUDA_TORCH && torch::cuda::is_available(); }

GraphedForward::GraphedForward(const Network& network, const torch::Tensor& images, const torch::Tensor& plucker,
                               const torch::Tensor& rays_o, const torch::Tensor& rays_d_un, Precision precision) {
#if II_HAS_CUDA_TORCH
  if (!images.is_cuda())
    fail("CUDA graph: the inputs are on {}, capture needs them on a CUDA device", images.device().str());
  // Only now: LibTorch 2.x's CUDAGraph starts CUDA when constructed, which fails without a driver.
  captured_ = std::make_unique<Captured>();
  torch::InferenceMode inference;
  const c10::cuda::CUDAGuard device_guard(images.device());
  Captured& c = *captured_;
  c.images = images.clone();
  c.plucker = plucker.to(images.device()).clone();
  c.rays_o = rays_o.to(images.device()).clone();
  c.rays_d_un = rays_d_un.to(images.device()).clone();
  torch::cuda::synchronize(images.device().index());
  // Capture cannot use the legacy default stream. Warming up on the capture stream first
  // creates what must not be created during capture: cuBLAS handles and workspaces, the
  // attention kernel choice, and the network's cached bf16 and fused head weights.
  c10::cuda::CUDAStream stream = c10::cuda::getStreamFromPool(false, images.device().index());
  {
    const c10::cuda::CUDAStreamGuard stream_guard(stream);
    for (int i = 0; i < 3; ++i) network.forward(c.images, c.plucker, c.rays_o, c.rays_d_un, precision);
    stream.synchronize();
    c.graph.capture_begin();
    c.maps = network.forward(c.images, c.plucker, c.rays_o, c.rays_d_un, precision).gaussians;
    c.graph.capture_end();
  }
  stream.synchronize();
#else
  (void)network, (void)plucker, (void)rays_o, (void)rays_d_un, (void)precision;
  fail("CUDA graph: this build's LibTorch has no CUDA (inputs on {})", images.device().str());
#endif
}

GraphedForward::~GraphedForward() = default;

const GaussianMaps& GraphedForward::run(const torch::Tensor& images, const torch::Tensor& plucker,
                                        const torch::Tensor& rays_o, const torch::Tensor& rays_d_un) {
  Captured& c = *captured_;
  const std::pair<const torch::Tensor*, torch::Tensor*> copies[] = {
      {&images, &c.images}, {&plucker, &c.plucker}, {&rays_o, &c.rays_o}, {&rays_d_un, &c.rays_d_un}};
  for (const auto& [from, to] : copies) {
    if (from->sizes() != to->sizes())
      fail("CUDA graph: input of shape [{}] given, the graph was captured for [{}]", fmt::join(from->sizes(), ", "),
           fmt::join(to->sizes(), ", "));
  }
  torch::InferenceMode inference;
  for (const auto& [from, to] : copies) to->copy_(*from, /*non_blocking=*/true);
#if II_HAS_CUDA_TORCH
  c.graph.replay();
#endif
  return c.maps;
}

}  // namespace ii
