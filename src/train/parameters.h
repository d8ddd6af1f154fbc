#pragma once
// What the optimiser updates, in the official parametrisation (spec §2.1-2.2): the patch
// convolutions and the cls token as they are, every Linear of the decoder and the upsampler
// as a weight-norm pair under the official names, `<layer>.weight_g` (out, 1) and
// `<layer>.weight_v` (out, in), with W = g · v / ‖v‖ (row norms, no epsilon). The Network
// holds the folded W; bind() recomputes it from these tensors so that gradients reach g and v.
#include <string>
#include <utility>
#include <vector>

#include "common/torch.h"

#include "model/checkpoint.h"
#include "model/network.h"

namespace ii {

class TrainableParameters {
 public:
  // From the network's current weights: g = row norms of W, v = W (so W is unchanged).
  // The tensors are fresh leaves that require gradients.
  explicit TrainableParameters(const Network& network);

  // Official names and tensors, in a fixed order.
  const std::vector<std::string>& names() const { return names_; }
  const std::vector<torch::Tensor>& tensors() const { return tensors_; }

  // The network's weights (named_parameters() order) from these tensors; differentiable
  // when grad mode is on.
  std::vector<torch::Tensor> network_weights() const;
  // network.set_parameters(network_weights()).
  void bind(Network& network) const;

  // Copies values in by official name (weight_g/weight_v for weight-normed layers). Strict:
  // missing, unexpected or mis-shaped tensors are an error naming them and `source`.
  void load(const StateDict& state, const std::string& source);
  // Takes the g and v of every weight-normed layer found in `pairs` (as a file stores them,
  // Checkpoint::weight_norm): fine-tuning then continues in the file's parametrisation
  // rather than the equivalent g = ‖W‖, v = W. Returns the number of layers taken; a pair
  // with the wrong shape is an error naming `source`.
  int load_weight_norm(const StateDict& pairs, const std::string& source);

  void to(const torch::Device& device);

 private:
  struct Source {
    int plain = -1;       // index into tensors_ when not weight-normed
    int g = -1, v = -1;   // else the pair
  };
  std::vector<std::string> names_;
  std::vector<torch::Tensor> tensors_;
  std::vector<Source> sources_;  // one per network parameter
};

// The 3 -> 4 image-channel expansion when inpainting training starts from an RGB-only
// (stage-1) model (spec §2.3): the mask channel's kernel is the mean of the three RGB
// kernels. Returns the state unchanged when it already has 4 channels.
StateDict expand_image_channels(StateDict state);

}  // namespace ii
