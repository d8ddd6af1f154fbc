#include "geometry/region_cover.h"

#include "common/error.h"
#include "geometry/surface_splats.h"

namespace ii {

GaussianSet region_cover_gaussians(const PreparedView& reference, const Camera& camera, const torch::Tensor& depth,
                                   const RegionCoverOptions& options, const torch::Tensor& like) {
  if (options.opacity <= 0 || !reference.mask) return {};
  const Image& mask = *reference.mask;
  if (depth.dim() != 2 || depth.size(0) != mask.height || depth.size(1) != mask.width)
    fail("region cover: the reference's depth is not its mask's size ({}x{})", mask.width, mask.height);
  const torch::Tensor region =
      torch::from_blob(const_cast<float*>(mask.pixels.data()), {mask.height, mask.width}, torch::kFloat32).gt(0.5);
  if (!region.any().item<bool>()) return {};
  GaussianSet cover = surface_gaussians(camera, depth.to(torch::kCPU, torch::kFloat32), region, reference.rgb,
                                        static_cast<float>(options.opacity));
  for (torch::Tensor* t : {&cover.means, &cover.quats, &cover.scales, &cover.opacities, &cover.colors})
    *t = t->to(like.device(), like.scalar_type());
  return cover;
}

nlohmann::json describe_region_cover(const RegionCoverOptions& options, int64_t gaussians) {
  return {{"opacity", options.opacity}, {"gaussians", gaussians}};
}

}  // namespace ii
