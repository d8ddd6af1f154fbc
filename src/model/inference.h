#pragma once
// One inference run: network on a prepared scene input, Gaussians out.
#include <string>

#include "model/network.h"
#include "model/scene_input.h"

namespace ii {

// Moves the tensors the network reads (images, Plücker rays, ray origins and directions) to
// `device` through pinned memory, so that the network can run there.
void upload_network_inputs(ModelInput& input, const torch::Device& device);

// Runs the network on `input` (one scene, no batch dimension) without gradients.
GaussianMaps run_network(const Network& network, const ModelInput& input, Precision precision);

// Checks that a model can take this input (channels, patch multiple) with a clear message.
void check_model_fits_input(const ModelConfig& config, const ModelInput& input, const std::string& model_source);

}  // namespace ii
