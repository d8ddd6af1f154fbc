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

SplatCloud to_splat_cloud(const GaussianMaps& maps) {
  // (1, V, C, H, W) -> (V*H*W, C)
  auto flat = [](const torch::Tensor& t) {
    return t[0].permute({0, 2, 3, 1}).reshape({-1, t.size(2)}).to(torch::kCPU, torch::kFloat32).contiguous();
  };
  auto to_vec = [](const torch::Tensor& t) {
    return std::vector<float>(t.data_ptr<float>(), t.data_ptr<float>() + t.numel());
  };
  constexpr double kSh0 = 0.28209479177387814;  // Y_0^0: colour = 0.5 + kSh0 * dc
  const torch::Tensor opacity = flat(maps.opacity).clamp(1e-6, 1.0 - 1e-6);
  SplatCloud c;
  c.means = to_vec(flat(maps.xyz));
  c.normals.assign(c.means.size(), 0.f);
  c.sh_dc = to_vec(((flat(maps.rgb) - 0.5) / kSh0).contiguous());
  c.opacity_logit = to_vec(torch::log(opacity / (1.0 - opacity)).reshape({-1}).contiguous());
  c.log_scales = to_vec(torch::log(flat(maps.scale)).contiguous());
  c.rotations = to_vec(flat(maps.rotation));
  return c;
}

}  // namespace ii
