#include "model/inference.h"

#include "common/error.h"
#include "model/device.h"

namespace ii {

void check_model_fits_input(const ModelConfig& config, const ModelInput& input, const std::string& model_source) {
  if (config.image_channels == 3)
    fail("{}: this is an RGB-only (stage-1 reconstruction) model; inpainting needs a model with "
         "the mask channel (4 input channels)", model_source);
  const int64_t H = input.images.size(2), W = input.images.size(3);
  if (H % config.patch != 0 || W % config.patch != 0)
    fail("{}: patch size {} does not divide the working size {}x{}; choose --height as a multiple of {}",
         model_source, config.patch, W, H, config.patch);
}

void upload_network_inputs(ModelInput& input, const torch::Device& device) {
  for (torch::Tensor* t : {&input.images, &input.plucker, &input.rays_o, &input.rays_d_un})
    *t = to_device(*t, device);
}

GaussianMaps run_network(const Network& network, const ModelInput& input, Precision precision) {
  torch::InferenceMode guard;
  return network
      .forward(input.images.unsqueeze(0), input.plucker.unsqueeze(0), input.rays_o.unsqueeze(0),
               input.rays_d_un.unsqueeze(0), precision)
      .gaussians;
}

}  // namespace ii
