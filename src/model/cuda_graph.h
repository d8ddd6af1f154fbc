#pragma once
// The network's forward pass for one fixed input shape, captured once as a CUDA graph and
// then replayed: one launch for the few hundred kernels of a forward pass, so that small
// inputs are no longer bound by launch overhead. Needs a CUDA build of LibTorch; elsewhere
// available() is false and constructing one says why.
#include <memory>

#include "common/torch.h"

#include "model/network.h"

namespace ii {

class GraphedForward {
 public:
  static bool available();

  // Warms up and captures `network` (already on the inputs' CUDA device) for inputs shaped
  // like these; `network` must outlive this object and keep its weights.
  GraphedForward(const Network& network, const torch::Tensor& images, const torch::Tensor& plucker,
                 const torch::Tensor& rays_o, const torch::Tensor& rays_d_un, Precision precision);
  ~GraphedForward();
  GraphedForward(const GraphedForward&) = delete;
  GraphedForward& operator=(const GraphedForward&) = delete;

  // Copies the inputs (same shapes as at capture, any device) into the captured buffers and
  // replays. The maps are the graph's own buffers: the next run overwrites them.
  const GaussianMaps& run(const torch::Tensor& images, const torch::Tensor& plucker, const torch::Tensor& rays_o,
                          const torch::Tensor& rays_d_un);

 private:
  struct Captured;
  std::unique_ptr<Captured> captured_;
};

}  // namespace ii
